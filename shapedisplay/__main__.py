"""``python -m shapedisplay`` runs the command-line tool."""
from shapedisplay_cli.main import entry

entry()
