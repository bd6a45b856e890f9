"""All-or-nothing writes (pinquad.runs)."""

from __future__ import annotations

import os
import stat

import pytest

from pinquad.io.runs import atomic_write_bytes, atomic_write_json


def test_atomic_write_gives_an_ordinary_file_and_leaves_no_temporary(tmp_path):
    umask = os.umask(0o022)
    try:
        path = atomic_write_bytes(tmp_path / "sub" / "figure.png", b"\x89PNG data")
    finally:
        os.umask(umask)
    assert path.read_bytes() == b"\x89PNG data"
    assert stat.S_IMODE(path.stat().st_mode) == 0o644  # readable by others, like open()
    assert [p.name for p in path.parent.iterdir()] == ["figure.png"]


def test_atomic_write_json_writes_nan_as_null_and_a_failed_write_leaves_nothing(
        tmp_path, monkeypatch):
    path = atomic_write_json(tmp_path / "r.json", {"a": float("nan"), "b": [1.5]})
    assert path.read_text().replace(" ", "").replace("\n", "") == '{"a":null,"b":[1.5]}'

    def interrupted(src, dst):
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "replace", interrupted)
    with pytest.raises(KeyboardInterrupt):
        atomic_write_json(tmp_path / "r.json", {"a": 2.0})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]
    assert "null" in path.read_text()  # the earlier file is untouched
