"""``python -m pinquad.axis_inertia``: entry point; the command is
``pinquad.cli.axis_inertia.main``."""

import sys

from pinquad.cli.axis_inertia import main

if __name__ == "__main__":
    sys.exit(main())
