"""Entry point: ``toddlerbot <area> <verb>``. Each area lives in its own module and registers a Typer app here."""

from __future__ import annotations

import sys

import typer
from rich.console import Console
from rich.markup import escape

from toddlerbot.cli import actuator, chain, design, dp, hw, manip, model, rl, sim, sysid, teleop
from toddlerbot.cli import eval as eval_cli
from toddlerbot.errors import ToddlerbotError

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


def main() -> None:
    """Run the CLI; user-facing errors become one red line and exit code 2, never a traceback."""
    try:
        app()
    except ToddlerbotError as exc:
        # soft_wrap: one line whatever the terminal width (rich wraps at 80 columns when not on a terminal)
        Console(stderr=True, soft_wrap=True).print(f"[bold red]error:[/] {escape(str(exc))}", highlight=False)
        sys.exit(2)
    except KeyboardInterrupt:  # Ctrl-C outside a command's own handling (e.g. while it prints its result)
        sys.exit(130)


if __name__ == "__main__":
    main()
