"""Console shared by the CLI modules: wide enough for tables when piped to a file."""

import sys

from rich.console import Console

console = Console(width=None if sys.stdout.isatty() else 160)
