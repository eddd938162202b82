import sys

from trackerd.cli.main import main

sys.exit(main())
