"""The README, the docs and the code's text describe the product, not its development:
no reference to a development issue, a development stop or a section of a design
document the reader does not have (history lives in CHANGELOG.md, which is not checked),
and no docs page too long to read."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# The same paths and pattern as
#   grep -rniE "\bstops? [0-9]+|\bissue [0-9]+|DESIGN (§|[0-9])" README.md docs pinquad viz \
#       estimators flightgen scripts pyproject.toml
CHECKED = ("README.md", "docs", "pinquad", "viz", "estimators", "flightgen", "scripts",
           "pyproject.toml")
DEVELOPMENT_REFERENCE = re.compile(r"\bstops? [0-9]+|\bissue [0-9]+|DESIGN (§|[0-9])",
                                   re.IGNORECASE)
# The same references broken across a line (checked on the whole text of each file).
BROKEN_REFERENCE = re.compile(r"\bstops?\s*\n\s*[0-9]+|\bissue\s*\n\s*[0-9]+|DESIGN\s*\n\s*(§|[0-9])",
                              re.IGNORECASE)
MAX_DOC_LINES = 650


def _text_files():
    for name in CHECKED:
        path = ROOT / name
        files = [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.is_file())
        for p in files:
            if "__pycache__" in p.parts or p.name == "CHANGELOG.md":
                continue
            data = p.read_bytes()
            if b"\0" in data:  # binary (figures, compiled files)
                continue
            yield p, data.decode("utf-8", errors="replace")


def test_no_issue_stop_or_design_section_references():
    found = [f"{p.relative_to(ROOT)}:{n}: {line.strip()}"
             for p, text in _text_files()
             for n, line in enumerate(text.splitlines(), 1)
             if DEVELOPMENT_REFERENCE.search(line)]
    found += [f"{p.relative_to(ROOT)}:{text.count(chr(10), 0, m.start()) + 1}: {m.group(0)!r}"
              for p, text in _text_files() for m in BROKEN_REFERENCE.finditer(text)]
    assert found == [], "development references (history goes to CHANGELOG.md):\n" + "\n".join(found)


def test_docs_pages_are_short_enough_to_read():
    long = [f"docs/{p.name}: {n} lines" for p in sorted((ROOT / "docs").glob("*.md"))
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_DOC_LINES]
    assert long == []
