"""``python -m pinquad.yaw``: entry point; the command is ``pinquad.cli.yaw.main``."""

import sys

from pinquad.cli.yaw import main

if __name__ == "__main__":
    sys.exit(main())
