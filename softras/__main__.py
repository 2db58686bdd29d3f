"""``python -m softras``: the softras command line (see :mod:`softras.cli`)."""

import sys

from softras.cli import main

if __name__ == "__main__":
    sys.exit(main())
