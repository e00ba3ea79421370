"""Command-line front end of shapedisplay (installed as ``shapedisplay.cli``).

Commands parse arguments and call the library; they hold no logic of their own.
"""
