"""`toddlerbot motion edit`: the keyframe motion editor in the browser (extra `[viz]`)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer

from toddlerbot.cli.options import MotorParamsOption, RobotOptions
from toddlerbot.cli.output import console
from toddlerbot.cli.output_paths import output_file
from toddlerbot.errors import ToddlerbotError

app = typer.Typer(help="Keyframe motions: edit them in the browser.", no_args_is_help=True)


@app.command()
def edit(
    motion: Annotated[str | None, typer.Argument(
        help="Motion to open: a built-in (squat, wave, look_around, get_up_front, ...) or a motion YAML file; none: a "
             "new motion.")]
        = None,
    port: Annotated[int, typer.Option("--port", min=0, max=65535,
                                      help="Port to serve the page on (0: any free port; a busy port: the next).")]
        = 8080,
    host: Annotated[str, typer.Option("--host", help="Address to listen on; the default serves this computer "
                                      "only (use SSH port forwarding from another one).")] = "127.0.0.1",
    out: Annotated[Path | None, typer.Option("--out", "-o", help="File Save writes (default: the opened file; "
                                             "a built-in motion needs a name, in the page or here).")] = None,
    motor_params: MotorParamsOption = None,
) -> None:
    """Serve the motion editor: the robot in 3D, joint sliders per limb, keyframes (add, delete, reorder,
    duration, mirror), play in MuJoCo with the actuator model (upright? CoM and support polygon), save as
    motion YAML. Runs until Ctrl-C. Over SSH: `ssh -L 8080:localhost:8080 ROBOT`, then open
    http://localhost:8080 on your computer."""
    try:
        import viser  # noqa: F401
    except ImportError:
        raise ToddlerbotError("the motion editor needs viser: pip install -e '.[viz]'") from None
    from toddlerbot.motion_editor.app import check_save_path, open_editor
    from toddlerbot.motion_editor.opening import open_keyframes

    robot = RobotOptions.of(motor_params=motor_params)
    description = robot.description()
    keyframes, save_to = open_keyframes(motion, description, out)
    if out is not None:  # the opened motion itself may be saved over: that is what an editor does
        check_save_path(str(out))
        output_file(out, "--out", robot.files)
    _check_host(host)
    _serve(open_editor(description, keyframes, save_to, host, port), host, port)


def _serve(editor, host: str, port: int) -> None:
    """Say where the page is and serve it until Ctrl-C."""
    actual = editor.server.get_port()
    moved = f" (port {port} was busy)" if port not in (0, actual) else ""
    console.print(f"motion editor: http://{'localhost' if host in ('127.0.0.1', 'localhost') else host}:{actual}"
                  f"{moved}\nfrom another computer: ssh -L {actual}:localhost:{actual} THIS_HOST, then open "
                  f"http://localhost:{actual}\nCtrl-C stops it", highlight=False, soft_wrap=True)
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        console.print("motion editor stopped")
    finally:
        editor.server.stop()


def _check_host(host: str) -> None:
    """One line for an address this computer cannot listen on (viser would retry port after port forever)."""
    import socket

    try:
        family = socket.getaddrinfo(host, None)[0][0]
        with socket.socket(family, socket.SOCK_STREAM) as probe:
            probe.bind((host, 0))
    except (OSError, UnicodeError) as exc:
        raise ToddlerbotError(f"--host {host}: cannot listen there ({getattr(exc, 'strerror', None) or exc}); use "
                              "127.0.0.1 (this computer) or 0.0.0.0 (every network)") from None
