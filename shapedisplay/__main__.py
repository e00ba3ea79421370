"""``python -m shapedisplay`` runs the command-line tool."""
import sys

from shapedisplay_cli.main import main

sys.exit(main())
