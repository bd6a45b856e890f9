"""``python -m pinquad.bench``: the benchmark's command line (what it measures:
:mod:`pinquad.experiments.bench`). The benchmark re-invokes this command as
``python -m pinquad.bench --worker KIND --spec JSON`` for each measurement, in a fresh
process; those two options are hidden from ``--help``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from pinquad.cli.help import HelpFormatter
from pinquad.experiments.bench import DEFAULT_N, LARGE_N, PEERS, SECTIONS
from pinquad.experiments.bench_run import (
    BenchOptions,
    checks_failed,
    run_benchmark,
    run_checks,
)
from pinquad.experiments.bench_workers import worker_main
from pinquad.io.runs import OutputError, atomic_write_json, check_output_file
from pinquad.report.bench import format_checks, format_report


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m pinquad.bench``."""
    p = argparse.ArgumentParser(
        prog="python -m pinquad.bench",
        description="Benchmark the E-step against filterpy, pykalman, dynamax and GTSAM, "
                    "offline EM, the offline command and the online update.",
        formatter_class=HelpFormatter)
    p.add_argument("--out", type=Path, default=Path("bench.json"), help="JSON result file")
    p.add_argument("--n", type=int, nargs="+", default=list(DEFAULT_N),
                   help="E-step lengths (steps)")
    p.add_argument("--repeats", type=int, default=5, help="timed runs per figure")
    p.add_argument("--repeats-large", type=int, default=3,
                   help=f"timed runs per figure at N >= {LARGE_N:,}")
    p.add_argument("--timeout", type=float, default=120.0,
                   help="stop a peer whose single call takes longer [s]")
    p.add_argument("--peers", nargs="*", default=list(PEERS), choices=list(PEERS),
                   help="peers to compare with ours")
    p.add_argument("--only", nargs="+", choices=list(SECTIONS),
                   help="run only these sections (all when not given)")
    p.add_argument("--quick", action="store_true",
                   help="skip the end-to-end `python -m pinquad.offline` run (minutes)")
    p.add_argument("--no-memory", action="store_true", help="skip the memory measurements")
    p.add_argument("--profile", action="store_true",
                   help="also profile our E-step (at the N closest to 10,000)")
    p.add_argument("--seed", type=int, default=1, help="seed of the simulated base flight")
    p.add_argument("--check", type=int, metavar="N",
                   help="only run the correctness checks on an N-step case")
    p.add_argument("--worker", help=argparse.SUPPRESS)
    p.add_argument("--spec", help=argparse.SUPPRESS)
    return p


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark (or one worker, or the checks). Returns the exit code."""
    args = build_parser().parse_args(argv)
    if args.worker:
        return worker_main(args.worker, args.spec or "{}")
    if args.check is not None:
        results = run_checks(args.check, args.seed, args.peers)
        print(format_checks(results, args.check))
        return 1 if checks_failed(results) else 0
    if args.repeats < 1 or args.repeats_large < 1 or any(n < 2 for n in args.n):
        print("error: --repeats must be >= 1 and every --n >= 2", file=sys.stderr)
        return 2
    try:
        check_output_file(args.out)  # before a run of minutes, not after it
    except OutputError as exc:
        print(f"error: --out {exc}", file=sys.stderr)
        return 2
    sections = set(args.only or SECTIONS)
    if args.no_memory:
        sections.discard("memory")
    if args.quick:
        sections.discard("offline")
    options = BenchOptions(n=tuple(sorted(set(args.n))), repeats=args.repeats,
                           repeats_large=args.repeats_large, timeout_s=args.timeout,
                           peers=tuple(args.peers), sections=frozenset(sections),
                           profile=args.profile, seed=args.seed)
    command = "python -m pinquad.bench " + " ".join(argv if argv is not None
                                                     else sys.argv[1:])
    res = run_benchmark(options, command)
    text = format_report(res)
    print(text)
    if res.get("profile") and args.profile:
        print("\ncProfile of ours (sorted by own time):")
        print(res["profile"]["cprofile_text"])
    res.get("profile", {}).pop("cprofile_text", None)
    atomic_write_json(args.out, res)
    print(f"\nwrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
