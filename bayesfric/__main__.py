"""``python -m bayesfric`` runs the command-line interface."""

import sys

from bayesfric.cli import main

sys.exit(main())
