"""``python -m pinquad.data fetch crazyflie``: download the public Crazyflie data set
(IMRC Lab flights and thrust-stand runs, pinned commit, SHA-256 per file) into the user's
cache, where every real-data command finds it; ``check`` verifies a directory against the
registry; ``where`` prints the directory the real-data commands would read."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from urllib.parse import urlparse

import requests

from pinquad.io.crazyflie_files import COMMIT, CRAZYFLIE_FILES, REPOSITORY
from pinquad.io.datadir import ENV_VAR, cache_data_dir, default_data_dir, missing_data_hint
from pinquad.io.datafetch import check_directory, fetch_crazyflie

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2


def build_parser() -> argparse.ArgumentParser:
    """The command line: ``fetch|check|where crazyflie`` and their options."""
    parser = argparse.ArgumentParser(
        prog="python -m pinquad.data",
        description=f"The public Crazyflie data set ({len(CRAZYFLIE_FILES)} files of "
                    f"{REPOSITORY} at commit {COMMIT[:8]}, SHA-256 each): fetch it into "
                    f"the cache ({cache_data_dir()}), check a copy, or show where the "
                    "real-data commands look. Exit codes: 0 done, 1 a download failed or a "
                    "file differs from the registry, 2 bad usage.")
    sub = parser.add_subparsers(dest="command", required=True)
    fetch = sub.add_parser("fetch", help="download the data set into the cache")
    fetch.add_argument("dataset", choices=["crazyflie"])
    fetch.add_argument("--cache", type=Path, default=None,
                       help=f"directory to download into (default {cache_data_dir()})")
    source = fetch.add_mutually_exclusive_group()
    source.add_argument("--base-url", default=None,
                        help="raw-file URL prefix of the origin repository (default: "
                             "GitHub's raw files at the pinned commit)")
    source.add_argument("--mirror", default=None,
                        help="URL of a server laid out like the data directory "
                             "(imrc_brushed/jana00, thrust_stand/...), e.g. a lab's copy")
    check = sub.add_parser("check", help="check a directory's files against the registry")
    check.add_argument("dataset", choices=["crazyflie"])
    check.add_argument("--data", type=Path, default=None,
                       help=f"directory to check (default: where the commands look: "
                            f"${ENV_VAR}, ../shared/data/crazyflie, the cache)")
    where = sub.add_parser("where", help="print the directory the real-data commands read")
    where.add_argument("dataset", choices=["crazyflie"])
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the subcommand; returns the exit code (EXIT_OK, EXIT_FAILED, EXIT_USAGE)."""
    args = build_parser().parse_args(argv)
    if args.command == "where":
        print(default_data_dir())
        return EXIT_OK
    if args.command == "check":
        data = args.data if args.data is not None else default_data_dir()
        if not data.is_dir():
            print(f"error: {data}: no such directory; {missing_data_hint()}", file=sys.stderr)
            return EXIT_USAGE
        bad = [c for c in check_directory(data) if c.problem]
        for c in bad:
            print(f"{c.name}: {c.problem}")
        print(f"{data}: {len(CRAZYFLIE_FILES) - len(bad)} of {len(CRAZYFLIE_FILES)} files "
              "match the registry")
        return EXIT_FAILED if bad else EXIT_OK
    try:
        where_to = fetch_crazyflie(args.cache, base_url=args.base_url, mirror=args.mirror)
    except requests.ConnectionError as exc:
        host = urlparse(exc.request.url).netloc if exc.request is not None else "the origin"
        print(f"error: fetch failed: cannot reach {host} (no network, or a name that does "
              "not resolve); the files already checked stay in the cache. Run the same "
              "command where the network reaches it (set HTTPS_PROXY behind a proxy), or "
              f"download from a copy with --mirror URL. ({type(exc).__name__})",
              file=sys.stderr)
        return EXIT_FAILED
    except (requests.RequestException, ValueError, OSError) as exc:
        print(f"error: fetch failed: {exc}", file=sys.stderr)
        return EXIT_FAILED
    total = sum(f.size for f in CRAZYFLIE_FILES)
    print(f"{len(CRAZYFLIE_FILES)} files ({total / 1e6:.1f} MB) of {REPOSITORY} at "
          f"{COMMIT[:8]} in {where_to}, SHA-256 checked")
    if args.cache is not None and args.cache.resolve() != cache_data_dir().resolve():
        print(f"not the default cache: give it to the real-data commands with --data "
              f"{where_to} or ${ENV_VAR}")
    return EXIT_OK
