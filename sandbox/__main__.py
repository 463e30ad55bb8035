"""``python -m sandbox``: the ``sandbox`` command (``sandbox/cli.py``), for a checkout without the script installed."""

import sys

from .cli import main

if __name__ == "__main__":  # importing the module (a tool walking the package) must not run the command
    sys.exit(main())
