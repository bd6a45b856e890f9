"""The public data set's registry and download (issue 23 part 1): the registry's SHA-256
match the shared copy byte for byte; a fetch through a local HTTP server (no network)
fills a cache the real-data commands then find without options; a file whose bytes
differ from the registry is refused; a command with no data says how to fetch it.
The shared data is required: missing data is a failure, not a skip."""

from __future__ import annotations

import functools
import http.server
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from pinquad.cli import data as data_cli
from pinquad.cli import realdata as realdata_cli
from pinquad.io import datadir
from pinquad.io.crazyflie_files import CRAZYFLIE_FILES
from pinquad.io.datafetch import check_directory, fetch_crazyflie, file_sha256
from pinquad.realdata.dataset import flights_dir, stand_dir
from pinquad.realdata.thrust import thrust_coefficient

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data" / "crazyflie"


@pytest.fixture(scope="module")
def shared() -> Path:
    if not (DATA / "imrc_brushed" / "jana00").is_file():
        pytest.fail(f"the shared Crazyflie data is required: {DATA} not found")
    return DATA


@pytest.fixture
def server(shared: Path) -> Iterator[str]:
    """A local HTTP server on a free port serving ``../shared/data``; yields its URL."""
    handler = functools.partial(_QuietHandler, directory=str(shared.parent))
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{httpd.server_address[1]}"
    finally:
        httpd.shutdown()
        httpd.server_close()


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format, *args):  # noqa: A002 - the base class's signature
        pass


def test_registry_matches_the_shared_data_byte_for_byte(shared: Path):
    checks = check_directory(shared)
    assert [c for c in checks if c.problem] == []
    assert len(checks) == len(CRAZYFLIE_FILES) == len({f.name for f in CRAZYFLIE_FILES})
    assert all(f.size == (shared / f.name).stat().st_size for f in CRAZYFLIE_FILES)


def test_registry_holds_every_file_the_real_data_commands_read(shared: Path):
    names = {f.name for f in CRAZYFLIE_FILES}
    read = [p.relative_to(shared).as_posix() for pattern in
            ("imrc_brushed/jana*", "imrc_brushless/eckart*", "thrust_stand/*.csv",
             "brushless_calibration/*.csv") for p in shared.glob(pattern)]
    assert len(read) == 28
    assert sorted(set(read) - names) == []


def test_fetch_through_a_local_server_fills_the_cache_the_commands_read(
        shared: Path, server: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.delenv(datadir.ENV_VAR, raising=False)
    # a user's install: no ../shared beside the package
    monkeypatch.setattr(datadir, "checkout_data_dir", lambda: tmp_path / "no_checkout")
    assert data_cli.main(["fetch", "crazyflie", "--mirror", f"{server}/crazyflie"]) == 0
    cache = tmp_path / "cache" / "pinquad" / "crazyflie"
    assert datadir.default_data_dir() == cache
    for f in CRAZYFLIE_FILES:
        assert file_sha256(cache / f.name) == file_sha256(shared / f.name) == f.sha256
    assert flights_dir() == cache / "imrc_brushed"
    assert sorted(p.name for p in flights_dir().glob("jana*")) == \
        sorted(p.name for p in (shared / "imrc_brushed").glob("jana*"))
    assert thrust_coefficient(stand_dir()).kf == thrust_coefficient(shared / "thrust_stand").kf
    # --data and the environment variable still win over the cache
    monkeypatch.setenv(datadir.ENV_VAR, str(shared))
    assert datadir.default_data_dir() == shared
    assert flights_dir(tmp_path) == tmp_path


def test_a_file_that_differs_from_the_registry_is_refused(
        shared: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    entry = next(f for f in CRAZYFLIE_FILES if f.name == "thrust_stand/cf21_stock2.csv")
    mirror = tmp_path / "mirror"
    (mirror / "thrust_stand").mkdir(parents=True)
    body = (shared / entry.name).read_bytes()
    (mirror / entry.name).write_bytes(body[:-1] + b"9")  # one byte changed
    handler = functools.partial(_QuietHandler, directory=str(mirror))
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    try:
        with pytest.raises(ValueError, match="SHA256"):
            fetch_crazyflie(tmp_path / "cache", mirror=f"http://127.0.0.1:{httpd.server_address[1]}",
                            files=(entry,))
    finally:
        httpd.shutdown()
        httpd.server_close()
    assert not (tmp_path / "cache" / entry.name).exists()


def test_no_data_anywhere_says_how_to_fetch_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                               capsys: pytest.CaptureFixture[str]):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.delenv(datadir.ENV_VAR, raising=False)
    monkeypatch.setattr(datadir, "checkout_data_dir", lambda: tmp_path / "no_checkout")
    assert realdata_cli.main([]) == 2
    err = capsys.readouterr().err
    assert "python -m pinquad.data fetch crazyflie" in err
    assert str(tmp_path / "cache" / "pinquad" / "crazyflie") in err
    assert data_cli.main(["check", "crazyflie"]) == 2
