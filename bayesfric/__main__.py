"""``python -m bayesfric`` runs the command-line interface."""

from bayesfric.cli import run

run()
