"""``python -m cmarlcd`` runs the command line."""

from cmarlcd.cli import app

app(prog_name="cmarl-cd")
