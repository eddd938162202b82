"""`python -m trackerd` runs the CLI (the guard keeps spawned worker processes from re-running it)."""

import sys

from trackerd.cli.main import main

if __name__ == "__main__":
    sys.exit(main())
