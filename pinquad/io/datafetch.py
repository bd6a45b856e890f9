"""Download the public Crazyflie data set into the user's cache with pooch, and check a
directory's files against the registry's SHA-256 (pinquad.io.crazyflie_files).

pooch does the downloading (HTTP, atomic writes, hash check, re-download of a changed
file); this module only says which files, from where, to where.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import pooch

from pinquad.io.crazyflie_files import CRAZYFLIE_FILES, ORIGIN_BASE_URL, CrazyflieFile
from pinquad.io.datadir import cache_data_dir


@dataclass(frozen=True)
class FileCheck:
    """One registry file checked in a directory.

    name: the file's path in the data directory.
    problem: "" when its bytes have the registry's SHA-256, else what is wrong
        ("missing", or "sha256 <found> != <expected>").
    """

    name: str
    problem: str


def file_sha256(path: Path) -> str:
    """Hex SHA-256 of the bytes of ``path``."""
    digest = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def check_directory(data: Path, files: Sequence[CrazyflieFile] = CRAZYFLIE_FILES
                    ) -> list[FileCheck]:
    """Check every registry file in ``data`` (a directory laid out like the cache):
    one FileCheck per file, in registry order."""
    checks = []
    for f in files:
        path = data / f.name
        if not path.is_file():
            checks.append(FileCheck(f.name, "missing"))
            continue
        found = file_sha256(path)
        checks.append(FileCheck(f.name, "" if found == f.sha256 else
                                f"sha256 {found} != {f.sha256}"))
    return checks


def file_urls(files: Sequence[CrazyflieFile], base_url: str | None = None,
              mirror: str | None = None) -> dict[str, str]:
    """Where each file is downloaded from: ``mirror + name`` when a mirror (a server laid
    out like the data directory: ``imrc_brushed/jana00``) is given, else ``base_url +
    upstream`` (default ``ORIGIN_BASE_URL``: the origin repository at the pinned commit)."""
    if mirror is not None:
        root = mirror if mirror.endswith("/") else mirror + "/"
        return {f.name: root + f.name for f in files}
    root = base_url or ORIGIN_BASE_URL
    root = root if root.endswith("/") else root + "/"
    return {f.name: root + f.upstream for f in files}


def fetch_crazyflie(cache: Path | None = None, base_url: str | None = None,
                    mirror: str | None = None, progress: bool = False,
                    files: Sequence[CrazyflieFile] = CRAZYFLIE_FILES) -> Path:
    """Download every registry file not already present with the right SHA-256 into
    ``cache`` (default ``cache_data_dir()``) and return that directory, which every
    real-data command then finds without options. Raises ``requests`` HTTP/connection
    errors or ValueError (a downloaded file whose SHA-256 differs from the registry's:
    pooch deletes it)."""
    target = cache if cache is not None else cache_data_dir()
    fetcher = pooch.create(path=target, base_url="",
                           registry={f.name: f"sha256:{f.sha256}" for f in files},
                           urls=file_urls(files, base_url, mirror))
    for f in files:
        fetcher.fetch(f.name, progressbar=progress)
    return Path(fetcher.abspath)
