"""``python -m pinquad.bench``: entry point; the command is
``pinquad.cli.bench.main``."""

import sys

from pinquad.cli.bench import main

if __name__ == "__main__":
    sys.exit(main())
