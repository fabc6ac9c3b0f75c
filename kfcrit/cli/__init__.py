"""cli layer: every command, exit handling and output-path checks (the top of the package)."""
from kfcrit.cli.main import main

__all__ = ["main"]
