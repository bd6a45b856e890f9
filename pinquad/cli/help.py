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
