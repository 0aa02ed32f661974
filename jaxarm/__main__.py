"""``python -m jaxarm`` runs the command-line tool."""

import sys

from jaxarm.cli import main

if __name__ == "__main__":
    sys.exit(main())
