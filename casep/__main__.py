"""``python -m casep``: the command line."""

import sys

from casep.cli import main

sys.exit(main())
