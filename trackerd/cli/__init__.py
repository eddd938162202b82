"""The `trackerd` command line: one module per subcommand, found by main.py.

Each module here that defines ``register(subparsers)`` adds its subcommand(s).
A command handler returns the process exit code; trackerd's own errors
(:class:`trackerd.errors.TrackerdError`) are printed as one line by main.py.
"""
