"""``python -m pinquad.online``: entry point; the command is
``pinquad.experiments.online.main``."""

import sys

from pinquad.experiments.online import main

if __name__ == "__main__":
    sys.exit(main())
