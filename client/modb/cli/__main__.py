"""`python -m modb.cli ...`: the `modb` command."""

import sys

from .main import main

if __name__ == "__main__":
    sys.exit(main())
