"""``python -m pinquad.bench``: entry point; the command is
``pinquad.experiments.bench.main``."""

import sys

from pinquad.experiments.bench import main

if __name__ == "__main__":
    sys.exit(main())
