"""Entry point: ``toddlerbot <area> <verb>``. Each area lives in its own module and registers a Typer app here."""

from __future__ import annotations

import sys

import typer
from rich.console import Console
from rich.markup import escape

from toddlerbot.cli import actuator, chain, design, dp, hw, manip, model, motion, rl, sim, sysid, teleop
from toddlerbot.cli import eval as eval_cli
from toddlerbot.errors import ToddlerbotError

try:  # typer >= 0.20 vendors click
    from typer._click import exceptions as click_errors
except ImportError:  # pragma: no cover - older typer depends on click itself
    from click import exceptions as click_errors

app = typer.Typer(
    help="ToddlerBot: robot model, design metrics, simulation, system identification and hardware tools.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
)
app.add_typer(model.app, name="model")
app.add_typer(design.app, name="design")
app.add_typer(sim.app, name="sim")
app.add_typer(actuator.app, name="actuator")
app.add_typer(sysid.app, name="sysid")
app.add_typer(hw.app, name="hw")
app.add_typer(rl.app, name="rl")
app.add_typer(eval_cli.app, name="eval")
app.add_typer(dp.app, name="dp")
app.add_typer(manip.app, name="manip")
app.add_typer(teleop.app, name="teleop")
app.add_typer(chain.app, name="chain")
app.add_typer(motion.app, name="motion")


def main() -> None:
    """Run the CLI. Exit codes (README, "Command line"): 0 done; 1 the run failed its own success check (a fall, a
    failed chain); 2 one red line instead of a traceback: bad input (options, files) or an error that stopped the
    command; 128 + N stopped by signal N."""
    try:
        # not standalone: typer's usage errors come back here and become the same one line as every other error
        code = app(standalone_mode=False)
    except click_errors.ClickException as exc:
        if isinstance(exc, getattr(click_errors, "NoArgsIsHelpError", ())):
            exc.show()  # `toddlerbot sim` alone: the help text, as before
            sys.exit(2)
        command = getattr(getattr(exc, "ctx", None), "command_path", "toddlerbot")
        _error(f"{command}: {' '.join(exc.format_message().split())} (see {command} --help)", exc.exit_code)
    except typer.Abort:  # EOF on a prompt
        sys.exit(1)
    except ToddlerbotError as exc:
        _error(str(exc), 2)
    except OSError as exc:  # the environment failed under a command (disk full, device gone): one line, not a traceback
        _error(f"{exc.filename}: {exc.strerror}" if exc.filename and exc.strerror else f"{type(exc).__name__}: {exc}",
               2)
    except KeyboardInterrupt:  # Ctrl-C outside a command's own handling (e.g. while it prints its result)
        sys.exit(130)
    sys.exit(code if isinstance(code, int) else 0)


def _error(message: str, code: int) -> None:
    # soft_wrap: one line whatever the terminal width (rich wraps at 80 columns when not on a terminal); no emoji:
    # a quoted ":x:" (a passwd line) stays text
    Console(stderr=True, soft_wrap=True, emoji=False).print(
        f"[bold red]error:[/] {escape(' '.join(message.splitlines()))}", highlight=False)
    sys.exit(code)


if __name__ == "__main__":
    main()
