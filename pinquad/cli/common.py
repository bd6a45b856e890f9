"""What the command lines share: the online commands'
``--memory`` value and its description (the measured-flight diagnostics' log arguments
are in ``pinquad.cli.measured``)."""

from __future__ import annotations

import argparse
import math


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


def memory_label(memory_s: float | None) -> str:
    """How the online M-step remembers samples that left the window, in words."""
    if memory_s is None:
        return "window only"
    if math.isinf(memory_s):
        return "every airborne sample (incremental EM)"
    return f"forgotten with time constant {memory_s:g} s"

