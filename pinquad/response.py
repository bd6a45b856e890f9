"""``python -m pinquad.response``: entry point; the command is
``pinquad.realdata.response.main``."""

import sys

from pinquad.realdata.response import main

if __name__ == "__main__":
    sys.exit(main())
