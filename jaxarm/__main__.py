"""``python -m jaxarm`` runs the command-line tool."""

import sys

from jaxarm.cli import main

sys.exit(main())
