"""The error every log reader raises for a file it cannot read as a flight log."""

from __future__ import annotations


class LogFormatError(ValueError):
    """A log file that does not follow the format: the message names the file, the
    column or byte offset, and what was expected."""


Problem = tuple[str, str, str]
"""What a physics check of a log found wrong: (check name, column(s) concerned, message),
as ``pinquad.io.sanity.Finding`` reports it."""
