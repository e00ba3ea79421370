"""``python -m shapedisplay`` runs the command-line tool."""
from shapedisplay.cli.main import entry

entry()
