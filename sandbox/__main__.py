"""``python -m sandbox``: the ``sandbox`` command (``sandbox/cli.py``), for a checkout without the script installed."""

import sys

from .cli import main

sys.exit(main())
