"""A run directory written by a task that may run again (``RunWriter(replace=True)``,
``Result.save(run_dir, replace=True)``): the rerun replaces the earlier output and what
a killed attempt left half written; without replace, an existing run is refused."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from pinquad.io.runs import OutputError, RunWriter


def _write(target: Path, text: str, replace: bool) -> Path:
    writer = RunWriter(target, replace=replace)
    with writer:
        writer.path("report.json").write_text(text)
        return writer.publish()


def test_a_rerun_replaces_its_own_output_and_a_killed_attempts_leftovers(tmp_path: Path):
    target = tmp_path / "logs" / "jana00"
    _write(target, "first", replace=True)
    (target / "stale.png").write_text("from the first attempt")
    # what a killed attempt leaves: its staging folder and the folder a publish set aside
    partial = tmp_path / "logs" / ".jana00.partial"
    partial.mkdir()
    (partial / "report.json").write_text("half")
    (tmp_path / "logs" / ".jana00.replaced").mkdir()
    umask = os.umask(0o027)
    try:
        final = _write(target, "second", replace=True)
    finally:
        os.umask(umask)
    assert final == target
    assert sorted(p.name for p in target.iterdir()) == ["report.json"]
    assert (target / "report.json").read_text() == "second"
    assert sorted(p.name for p in (tmp_path / "logs").iterdir()) == ["jana00"]
    assert stat.S_IMODE(target.stat().st_mode) == 0o750  # the user's umask, not 0700


def test_without_replace_an_existing_run_is_refused_and_kept(tmp_path: Path):
    target = tmp_path / "run"
    _write(target, "first", replace=False)
    with pytest.raises(OutputError, match="exists and is not empty"):
        RunWriter(target)
    assert (target / "report.json").read_text() == "first"
