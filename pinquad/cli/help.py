"""The ``--help`` formatter every command line uses (the viewer's too, which imports
nothing else of pinquad's command layer)."""

from __future__ import annotations

import argparse


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Appends "(default: ...)" to an option's help only where it says something: not
    when the default is None or False (the help then says what happens), nor when the
    help already names its default."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if action.default is None or action.default is False or "(default" in text:
            return text
        return super()._get_help_string(action)


def whole_number_at_least(text: str, minimum: int) -> int:
    """``text`` as a whole number >= ``minimum``, else argparse's type error."""
    try:
        value = int(text)
    except ValueError:
        value = minimum - 1
    if value < minimum:
        raise argparse.ArgumentTypeError(f"expected a whole number >= {minimum}, got {text!r}")
    return value


def non_negative_float(text: str) -> float:
    """An argument that must be a finite number >= 0 (a mass in kg, 0 included)."""
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not (value >= 0.0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text!r}")
    return value


def non_negative_int(text: str) -> int:
    """An argument that must be a whole number >= 0 (0 switches something off)."""
    return whole_number_at_least(text, 0)


def positive_int(text: str) -> int:
    """An argument that must be a whole number >= 1 (cycles, iterations, workers)."""
    return whole_number_at_least(text, 1)
