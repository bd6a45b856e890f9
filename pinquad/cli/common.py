"""What the command lines share: the check of ``--out`` before any work
(``output_problem``), the online commands'
``--memory`` value and its description (the measured-flight diagnostics' log arguments
are in ``pinquad.cli.measured``)."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from pinquad.io.runs import OutputError, check_output_directory, check_output_file


def memory_arg(text: str) -> float | None:
    """The online commands' --memory: a positive number of seconds, inf, or none."""
    if text.strip().lower() == "none":
        return None
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected seconds (> 0), inf or none, got {text!r}") from None
    if not value > 0.0:
        raise argparse.ArgumentTypeError(f"expected seconds (> 0), inf or none, got {text!r}")
    return value


def output_problem(path: Path | None, directory: bool) -> int | None:
    """Check ``--out`` before any work (``pinquad.io.runs``): None when it can be written
    (or is not given), else print a located error and return exit code 2."""
    if path is None:
        return None
    try:
        (check_output_directory if directory else check_output_file)(path)
    except OutputError as exc:
        print(f"error: --out {exc}", file=sys.stderr)
        return 2
    return None


def memory_label(memory_s: float | None) -> str:
    """How the online M-step remembers samples that left the window, in words."""
    if memory_s is None:
        return "window only"
    if math.isinf(memory_s):
        return "every airborne sample (incremental EM)"
    return f"forgotten with time constant {memory_s:g} s"

