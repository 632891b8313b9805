"""`toddlerbot manip ...`: scripted demonstrations, their success rate, and LeRobot v3.0 dataset checks."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from toddlerbot.cli.options import seed_option
from toddlerbot.cli.output import console
from toddlerbot.cli.output_paths import output_dir, output_file
from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import json_text

app = typer.Typer(help="Manipulation: scripted demonstrations, datasets (LeRobot v3.0).", no_args_is_help=True)
dataset_app = typer.Typer(help="Inspect and validate LeRobot v3.0 datasets.", no_args_is_help=True)
app.add_typer(dataset_app, name="dataset")

TASK_HELP = ("Task: pick (lift the cube and hold it for 1 s) or wagon (grasp the wagon handle with both hands); "
             "NAME:VARIATION for one of its declared scene variations, e.g. wagon:wide.")


def _check_task(task: str) -> None:
    from toddlerbot.tasks import TASKS, task_name

    if task_name(task) not in TASKS:
        raise ToddlerbotError(f"unknown task {task!r}; expected one of {', '.join(TASKS.names())}")


TaskOption = Annotated[str, typer.Option("--task", help=TASK_HELP)]
DatasetOutOption = Annotated[Path, typer.Option("-o", "--out", help="Dataset directory to write (LeRobot v3.0 + "
                                                                     "raw/).")]
EpisodesOption = Annotated[int, typer.Option("--episodes", min=1, max=10_000, help="Successful episodes to record.")]
VideoOption = Annotated[Path | None, typer.Option("--video", help="MP4: scene camera and head camera side by side.")]
SnapshotOption = Annotated[Path | None, typer.Option("--snapshot", help="PNG of one video frame (needs --video).")]


@app.command()
def demo(
    out: DatasetOutOption,
    task: TaskOption = "pick",
    episodes: EpisodesOption = 10,
    seed: Annotated[int, seed_option("First scene seed (then seed+1, ...).")] = 0,
    video: VideoOption = None,
    snapshot: SnapshotOption = None,
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace an existing dataset.")] = False,
) -> None:
    """Record scripted demonstrations of a task (50 Hz raw episodes, 10 Hz LeRobot v3.0 dataset)."""
    from rich.progress import Progress

    from toddlerbot.tasks.record import record_demos

    _check_task(task)
    _check_demo_outputs(out, video, snapshot, overwrite)
    with Progress(console=console, transient=True) as progress:
        bar = progress.add_task(f"recording {task} demonstrations", total=episodes)

        def on_episode(episode_seed: int, success: bool) -> None:
            if success:
                progress.advance(bar)
            else:
                progress.console.print(f"seed {episode_seed}: demonstration failed, not recorded")

        report = record_demos(out, episodes, seed, task, video_path=video, overwrite=overwrite, on_episode=on_episode,
                              snapshot_path=snapshot)
    if not report.succeeded_seeds:
        raise ToddlerbotError(f"no successful demonstration in seeds {seed}..{seed + len(report.failed_seeds) - 1}")
    console.print(f"wrote {out}: {len(report.succeeded_seeds)} episodes (seeds {report.succeeded_seeds[0]}.."
                  f"{report.succeeded_seeds[-1]}, {len(report.failed_seeds)} failed seed(s) skipped), "
                  f"{report.seconds_per_episode:.1f} s per episode")
    for path in (video, snapshot):
        if path:
            console.print(f"wrote {path}")


def _check_demo_outputs(out: Path, video: Path | None, snapshot: Path | None, overwrite: bool) -> None:
    """Every file `manip demo` writes is shown writable before the first episode runs."""
    if snapshot is not None and video is None:
        raise ToddlerbotError("--snapshot takes a frame of the video: give --video too")
    output_dir(out, "--out", empty=None if overwrite else "; pass --overwrite to replace it")
    for option, path in (("--video", video), ("--snapshot", snapshot)):
        if path is not None:
            output_file(path, option)


@app.command("demo-rate")
def demo_rate(
    task: TaskOption = "pick",
    episodes: Annotated[int, typer.Option("--episodes", min=1, max=10_000, help="Seeds to try.")] = 50,
    seed: Annotated[int, seed_option("First seed.")] = 0,
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON.")] = False,
) -> None:
    """Success rate of the scripted demonstrator over consecutive seeds (no rendering)."""
    from rich.progress import Progress

    from toddlerbot.tasks.record import demo_success_rate

    _check_task(task)
    with Progress(console=console, transient=True) as progress:
        bar = progress.add_task(f"{task} demonstrations", total=episodes)
        report = demo_success_rate(task, episodes, seed, on_episode=lambda *_: progress.advance(bar))
    failed = report.failed_seeds
    result = {"task": task, "episodes": episodes, "success_rate": report.success_rate, "failed_seeds": failed,
              "seconds_per_episode": report.seconds_per_episode}
    if as_json:
        print(json_text(result))
    else:
        console.print(f"{task}: success {result['success_rate']:.0%} over seeds {seed}..{seed + episodes - 1} "
                      f"(failed: {failed or 'none'}), {result['seconds_per_episode']:.1f} s per episode")


@dataset_app.command()
def decode(
    root: Annotated[Path, typer.Argument(help="Dataset directory.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Decoded copy to write (.npz).")],
) -> None:
    """Validate a dataset and write it decoded (images as arrays) to one .npz that trains without PyAV/pyarrow."""
    from toddlerbot.datasets.dataset import save_decoded
    from toddlerbot.datasets.lerobot_reader import load_dataset

    if out.suffix != ".npz":
        raise ToddlerbotError(f"--out {out}: expected a file name ending in .npz")
    output_file(out, "--out", [root])
    dataset = load_dataset(root)
    written = save_decoded(dataset, out)
    console.print(f"wrote {written}: {dataset.n_episodes} episodes, {len(dataset)} frames, "
                  f"{written.stat().st_size / 1e6:.1f} MB")


@dataset_app.command()
def info(
    root: Annotated[Path, typer.Argument(help="Dataset directory.")],
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON.")] = False,
) -> None:
    """Validate a LeRobot v3.0 dataset (files, row and frame counts, NaN rows) and print its summary."""
    from toddlerbot.datasets.lerobot_reader import load_dataset

    summary = load_dataset(root, decode_video=False).summary()
    if as_json:
        print(json_text(summary))
        return
    ep = summary["episode_seconds"]
    console.print(
        f"{summary['root']}: LeRobot {summary['codebase_version']}, {summary['episodes']} episodes, "
        f"{summary['frames']} frames at {summary['fps']} Hz (episodes {ep['min']:.1f}-{ep['max']:.1f} s, "
        f"mean {ep['mean']:.1f} s); state {summary['state_dim']}-d, action {summary['action_dim']}-d, "
        f"video {summary['image_shape']}; tasks: {', '.join(summary['tasks'])}"
    )


@dataset_app.command()
def view(
    root: Annotated[Path, typer.Argument(help="Dataset directory.")],
    episode: Annotated[int | None, typer.Option("--episode", help="Show only this episode (default: all, back "
                                                "to back).")] = None,
    save: Annotated[Path | None, typer.Option("--save", help="Write a Rerun recording (.rrd) instead of showing it; "
                                              "open it later with `rerun FILE.rrd`.")] = None,
    web: Annotated[bool, typer.Option("--web", help="Serve Rerun's web viewer even where a display exists.")]
        = False,
    port: Annotated[int, typer.Option("--port", min=1, max=65534, help="Web viewer port (its data stream uses "
                                      "--port + 1); forward both over SSH.")] = 9090,
) -> None:
    """Show a dataset in Rerun (extra `viz`): head-camera video, follower state and leader action per joint over
    time, episode boundaries and success. A native viewer opens where a display exists; elsewhere (over SSH) the
    web viewer is served until Ctrl-C."""
    _require_rerun()
    from toddlerbot.datasets.lerobot_reader import load_dataset
    from toddlerbot.datasets.view import choose_episodes, log_dataset, recording_for
    from toddlerbot.sim.render import has_display

    if save is not None:
        if save.suffix != ".rrd":
            raise ToddlerbotError(f"--save {save}: expected a file name ending in .rrd")
        output_file(save, "--save", [root])
    dataset = load_dataset(root)
    episodes = choose_episodes(dataset, episode)
    recording = recording_for(dataset)
    serve_web = save is None and (web or not has_display())
    uri = _open_viewer(recording, save, serve_web, port)
    summary = _sent_summary(root, episodes, log_dataset(dataset, episodes, recording))
    if save is not None:
        recording.flush()
        recording.disconnect()
        console.print(f"{summary}\nwrote {save} ({save.stat().st_size / 1e6:.2f} MB)", highlight=False)
    elif serve_web:
        _serve_web_until_interrupted(summary, uri, port)
    else:
        console.print(summary, highlight=False)


def _require_rerun() -> None:
    try:
        import rerun  # noqa: F401
    except ImportError:
        raise ToddlerbotError("the dataset viewer needs rerun-sdk: pip install -e '.[viz]'") from None


def _sent_summary(root: Path, episodes: list, sent: dict) -> str:
    said = ", ".join(f"{e}: {'-' if s is None else 'yes' if s else 'no'}" for e, s in sent["success"].items())
    return f"{root}: {len(episodes)} episode(s), {sent['frames']} frames ({sent['seconds']:.1f} s); success {said}"


def _open_viewer(recording, save: Path | None, serve_web: bool, port: int) -> str | None:
    """Where the recording goes: a file, the web viewer on `port` (its gRPC URI returned) or a native viewer."""
    import rerun as rr

    if save is not None:
        recording.save(save)
        return None
    if not serve_web:
        from toddlerbot.datasets.view import spawn_viewer

        spawn_viewer(recording)
        return None
    _check_free(port, port + 1)
    uri = recording.serve_grpc(grpc_port=port + 1)
    rr.serve_web_viewer(web_port=port, open_browser=False, connect_to=uri)
    return uri


def _serve_web_until_interrupted(summary: str, uri: str, port: int) -> None:
    import time
    from urllib.parse import quote

    console.print(f"{summary}\nRerun web viewer: http://localhost:{port}/?url={quote(uri, safe='')}\n"
                  f"over SSH: ssh -L {port}:localhost:{port} -L {port + 1}:localhost:{port + 1} ROBOT; "
                  "Ctrl-C stops it", highlight=False, soft_wrap=True)
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        console.print("viewer stopped")


def _check_free(*ports: int) -> None:
    """One line for a port already in use (Rerun's servers would not say so)."""
    import socket

    for port in ports:
        with socket.socket() as probe:
            try:
                probe.bind(("", port))
            except OSError as exc:
                raise ToddlerbotError(f"--port: port {port} is not free ({exc.strerror}); the web viewer uses --port "
                                      "and --port + 1, choose another --port") from None
