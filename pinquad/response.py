"""``python -m pinquad.response``: entry point; the command is
``pinquad.cli.response.main``."""

import sys

from pinquad.cli.response import main

if __name__ == "__main__":
    sys.exit(main())
