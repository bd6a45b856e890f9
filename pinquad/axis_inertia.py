"""``python -m pinquad.axis_inertia``: entry point; the command is
``pinquad.realdata.axis_inertia.main``."""

import sys

from pinquad.realdata.axis_inertia import main

if __name__ == "__main__":
    sys.exit(main())
