"""A CSV flight table's columns: its dialect found from the header line, decimal commas
read, and a column name that appears twice refused.

Spreadsheets in many locales write ``;`` between fields and ``,`` as the decimal mark
("1,25" for 1.25). The header line decides the separator: a header with no comma and
at least one ``;`` (or tab) is a ``;``- (tab-) separated file. In such a file a comma
inside a number can only be a decimal mark, so it is read as one and the log carries a
note saying so; a cell holding both ``.`` and ``,`` (a thousands separator as well) is
ambiguous and refused with its line and column. A header that names a column twice
is refused naming both positions: which of the two the rest of pinquad should read
cannot be guessed (a dict of columns kept the later one silently).
"""

from __future__ import annotations

import csv
import io
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pinquad.io.errors import LogFormatError

Array = NDArray[np.float64]

SEPARATORS = {";": "';'", "\t": "a tab"}
"""Field separators other than the comma, as the messages name them."""

DECIMAL_COMMA = re.compile(r"^[+-]?(\d+,\d*|,\d+)([eE][+-]?\d+)?$")
"""A number written with a decimal comma ("-1,25", "3,0e-05")."""


@dataclass(frozen=True)
class CsvTable:
    """A CSV file's columns: columns {name: (N,) values, NaN for an empty cell};
    notes: what was read differently from a plain comma-separated file (the dialect)."""

    columns: dict[str, Array]
    notes: tuple[str, ...] = ()


def duplicated_names(path: Path | str, names: list[str]) -> None:
    """Raise LogFormatError when a column name appears twice, naming it and both
    positions (1-based)."""
    seen: dict[str, int] = {}
    for k, name in enumerate(names):
        if name in seen:
            raise LogFormatError(
                f"{path}: column {name!r} appears twice in the header, as column "
                f"{seen[name] + 1} and column {k + 1} (of {len(names)}); which one holds the "
                "measurement cannot be told: remove or rename one of them")
        seen[name] = k


def _separator(header_line: str) -> str:
    """The field separator the header line uses: ',' unless it holds none and a ';' or
    a tab."""
    if "," in header_line:
        return ","
    for sep in SEPARATORS:
        if sep in header_line:
            return sep
    return ","


def read_csv_table(path: Path) -> CsvTable:
    """The columns of a CSV file (the standard library's reader: quoted names and cells,
    as spreadsheets and pyarrow write them, read as their text), in the dialect its
    header line shows (module docstring). Raises LogFormatError naming the file, the
    line and the column."""
    # utf-8-sig: a spreadsheet's byte-order mark is not part of the first column's name
    text = path.read_text(encoding="utf-8-sig", errors="replace")
    first = next((ln for ln in text.splitlines() if ln.strip()), "")
    sep = _separator(first)
    try:
        reader = csv.reader(io.StringIO(text), delimiter=sep)
        rows = [(reader.line_num, row) for row in reader if any(c.strip() for c in row)]
    except csv.Error as exc:
        raise LogFormatError(f"{path}: not a CSV table ({exc}); expected comma-separated "
                             "numbers under a header row of column names") from None
    if not rows:
        raise LogFormatError(f"{path}: empty file; expected a header row with column names")
    header = [h.strip() for h in rows[0][1]]
    duplicated_names(path, header)
    if len(rows) < 2:
        raise LogFormatError(f"{path}: no data rows after the header")
    data = np.full((len(rows) - 1, len(header)), np.nan)
    commas = 0
    where = "" if sep == "," else f" separated by {SEPARATORS[sep]}"
    for r, (line, cells) in enumerate(rows[1:]):
        if len(cells) != len(header):
            raise LogFormatError(
                f"{path}: line {line} has {len(cells)} fields{where}; expected {len(header)} "
                "(one per header column)")
        for c, cell in enumerate(cells):
            cell = cell.strip()
            if cell == "" or cell.lower() == "nan":
                continue
            if sep != "," and "," in cell:
                if not DECIMAL_COMMA.match(cell):
                    raise LogFormatError(
                        f"{path}: line {line}, column {header[c]!r}: {cell!r} is not a number "
                        f"with a decimal comma (the file separates fields by {SEPARATORS[sep]} "
                        "and writes ',' as the decimal mark); expected digits, one ',' and no "
                        "thousands separator")
                cell = cell.replace(",", ".")
                commas += 1
            try:
                data[r, c] = float(cell)
            except ValueError:
                raise LogFormatError(
                    f"{path}: line {line}, column {header[c]!r}: {cell!r} is not a number"
                ) from None
    notes: tuple[str, ...] = ()
    if sep != ",":
        mark = (f"',' as the decimal mark ({commas} cells)" if commas
                else "'.' as the decimal mark")
        notes = (f"read as a CSV separated by {SEPARATORS[sep]} with {mark}, as the header "
                 "line shows",)
    return CsvTable({name: data[:, i] for i, name in enumerate(header)}, notes)
