"""``python -m pinquad.discovery``: the seeded Monte Carlo of effect discovery through the
CSV ``--log`` path (``pinquad.experiments.discovery_mc``), or ``--merge`` of earlier runs'
cases; tables by ``pinquad.report.discovery_mc``. ``--generator flightgen``: the same on
flights of the independent generator at ``--log-rate`` 100 / 250 / 500 Hz
(``pinquad.experiments.discovery_mc_flightgen``)."""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from tqdm import tqdm

from pinquad.cli.common import add_backend_arguments, backend_from_args, output_problem
from pinquad.core.execution import BackendError, open_executor
from pinquad.experiments import discovery_mc_flightgen as fgmc
from pinquad.experiments.discovery_mc import (
    CONDITIONS,
    CaseJob,
    CaseResult,
    append_case,
    case_seed,
    read_cases,
    run_cases,
    summarize,
)
from pinquad.io.runs import atomic_write_json, new_run_dir
from pinquad.report.discovery_mc import discovery_mc_markdown
from pinquad.report.discovery_mc_flightgen import flightgen_mc_markdown


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m pinquad.discovery``."""
    p = argparse.ArgumentParser(prog="python -m pinquad.discovery",
                                description="Seeded Monte Carlo of effect discovery through "
                                            "the CSV --log path (module pinquad.discovery_mc).")
    p.add_argument("--seeds", type=int, default=20, help="seeds per condition")
    p.add_argument("--base-seed", type=int, default=0, help="base seed")
    p.add_argument("--generator", choices=("pinquad", "flightgen"), default="pinquad",
                   help="pinquad: pinquad's own simulator (default); flightgen: the independent "
                        "generator (RK4 on quaternions, geometric controller at 2 kHz, actuation "
                        "sampled at each log row, mocap at 100 Hz)")
    p.add_argument("--log-rate", type=int, nargs="+", default=list(fgmc.LOG_RATES),
                   choices=list(fgmc.LOG_RATES), help="flightgen only: log rates [Hz]")
    p.add_argument("--conditions", nargs="*", default=None,
                   help=f"conditions (pinquad: {', '.join(CONDITIONS)}; flightgen: "
                        f"{', '.join(fgmc.FG_CONDITIONS)}; default all)")
    add_backend_arguments(p, 1, "simulated flights")
    p.add_argument("--laps", type=int, default=1,
                   help="times round the route per flight (about 20 s a lap)")
    p.add_argument("--start-index", type=int, default=0,
                   help="first seed index i (to extend an earlier run with more seeds)")
    p.add_argument("--merge", type=Path, nargs="+", default=None,
                   help="only summarise these discovery_mc.json / cases.jsonl files together (a later file's "
                        "case replaces an earlier one with the same condition and seed)")
    p.add_argument("--out", type=Path, default=None, help="output directory (default runs/...)")
    return p


def main(argv: list[str] | None = None) -> int:
    """Run the Monte Carlo (or ``--merge``), print its tables and write discovery_mc.json,
    discovery_mc.md and cases.jsonl to ``--out``. Returns the exit code."""
    args = build_parser().parse_args(argv)
    if args.merge:
        if args.generator == "flightgen":
            return merge_flightgen(args.merge, args.out)
        return merge(args.merge, args.out)
    if args.seeds < 1 or args.laps < 1:
        print("error: --seeds and --laps must be at least 1", file=sys.stderr)
        return 2
    known = fgmc.FG_CONDITIONS if args.generator == "flightgen" else tuple(CONDITIONS)
    if args.conditions is None:
        args.conditions = list(known)
    unknown = [c for c in args.conditions if c not in known]
    if unknown:
        print(f"error: unknown condition(s) {', '.join(unknown)} for --generator "
              f"{args.generator}; choose from {', '.join(known)}", file=sys.stderr)
        return 2
    try:
        return run_flightgen(args) if args.generator == "flightgen" else run_pinquad(args)
    except BackendError as exc:  # raised before any flight runs
        print(f"error: {exc}", file=sys.stderr)
        return 2


def run_pinquad(args: argparse.Namespace) -> int:
    """The Monte Carlo on pinquad's own simulator: run, print the seeds and tables, write
    discovery_mc.json / .md and cases.jsonl to ``--out``. Returns 0, or 2 on a bad --out;
    raises BackendError when the backend cannot be had."""
    backend = backend_from_args(args)
    out = args.out or new_run_dir("discovery-mc")
    if (code := output_problem(out, directory=True)) is not None:
        return code
    jobs = [(c, case_seed(args.base_seed, c, i)) for c in args.conditions
            for i in range(args.start_index, args.start_index + args.seeds)]
    print(f"discovery Monte Carlo: {len(args.conditions)} condition(s) x {args.seeds} seeds, "
          f"base seed {args.base_seed} (seed = base*100000 + condition*1000 + i), {args.laps} "
          f"lap(s) of the route, {backend.describe()}")
    t0 = time.perf_counter()
    cases: list[CaseResult] = []
    with (tempfile.TemporaryDirectory(prefix="pinquad-dmc-") as tmp,
          open_executor(backend, len(jobs)) as executor):
        out.mkdir(parents=True, exist_ok=True)  # once the backend is had: nothing written before
        work = [CaseJob(c, s, tmp, args.laps) for c, s in jobs]
        for res in tqdm(run_cases(work, executor), total=len(work), unit="flight",
                        file=sys.stderr):
            cases.append(res)
            append_case(out, res)
    summary = summarize(cases)
    summary["seconds"] = time.perf_counter() - t0
    summary["base_seed"] = args.base_seed
    summary["seeds_per_condition"] = args.seeds
    summary["laps"] = args.laps
    table = discovery_mc_markdown(summary)
    print()
    for cond in args.conditions:
        seeds = [c.seed for c in cases if c.condition == cond]
        print(f"{cond}: seeds {seeds[0]}..{seeds[-1]}")
    print(table)
    print(f"\n{len(cases)} flights in {summary['seconds']:.0f} s")
    atomic_write_json(out / "discovery_mc.json", {"summary": summary,
                                                  "cases": [c.to_json() for c in cases]})
    (out / "discovery_mc.md").write_text("# Effect discovery Monte Carlo\n\n" + table + "\n")
    print(f"written to {out}")
    return 0


def run_flightgen(args: argparse.Namespace) -> int:
    """``--generator flightgen``: run, print the seeds and tables, write
    discovery_mc_flightgen.json / .md and cases.jsonl to ``--out``. Returns 0, or 2 on a
    bad --out; raises BackendError when the backend cannot be had."""
    backend = backend_from_args(args)
    out = args.out or new_run_dir("discovery-mc-flightgen")
    if (code := output_problem(out, directory=True)) is not None:
        return code
    print(f"flightgen discovery Monte Carlo: {len(args.conditions)} condition(s) x "
          f"{args.seeds} seeds x log rates {', '.join(map(str, args.log_rate))} Hz, base seed "
          f"{args.base_seed} (seed = base*100000 + condition*1000 + i, the same at every rate), "
          f"{backend.describe()}")
    t0 = time.perf_counter()
    cases: list[fgmc.FlightgenCase] = []
    with tempfile.TemporaryDirectory(prefix="pinquad-fgmc-") as tmp:
        work = fgmc.plan(args.conditions, args.log_rate, args.seeds, args.base_seed,
                         args.start_index, tmp)
        with open_executor(backend, len(work)) as executor:
            out.mkdir(parents=True, exist_ok=True)  # once the backend is had
            for res in tqdm(fgmc.run_cases(work, executor), total=len(work), unit="flight",
                            file=sys.stderr):
                cases.append(res)
                fgmc.append_case(out, res)
    rows = fgmc.summarize(cases)
    seconds = time.perf_counter() - t0
    print()
    for cond in args.conditions:
        seeds = sorted({c.seed for c in cases if c.condition == cond})
        print(f"{cond}: seeds {seeds[0]}..{seeds[-1]}")
    table = flightgen_mc_markdown(rows)
    print(table)
    print(f"\n{len(cases)} flights in {seconds:.0f} s")
    _write_flightgen(out, rows, table, cases, {"seconds": seconds, "base_seed": args.base_seed,
                                               "seeds_per_condition": args.seeds})
    return 0


def _write_flightgen(out: Path, rows: list[dict], table: str,
                     cases: list[fgmc.FlightgenCase], extra: dict) -> None:
    """A flightgen run's (or merge's) discovery_mc_flightgen.json (rows, ``extra``, cases)
    and .md (the tables) in ``out``."""
    atomic_write_json(out / "discovery_mc_flightgen.json",
                      {"rows": rows, **extra, "cases": [c.to_json() for c in cases]})
    (out / "discovery_mc_flightgen.md").write_text(
        "# Effect discovery Monte Carlo on flightgen flights\n\n" + table + "\n")
    print(f"written to {out}")


def merge(paths: list[Path], out: Path | None) -> int:
    """``--merge``: summarise several runs' cases together (later files win on duplicates);
    print the tables and, with ``out``, write them there. Returns the exit code."""
    cases: dict[tuple[str, int], CaseResult] = {}
    seen_laps: set[int] = set()
    for p in paths:
        try:
            read = read_cases(p)
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
            print(f"error: {p}: cannot read a discovery_mc.json or cases.jsonl of pinquad's "
                  f"simulator ({type(exc).__name__}: {exc}; a flightgen run's cases are merged "
                  f"with --generator flightgen)", file=sys.stderr)
            return 2
        for case in read:
            cases[(case.condition, case.seed)] = case
            seen_laps.add(case.laps)
    laps = sorted(seen_laps)
    if len(laps) > 1:
        print(f"error: the files mix flights of {', '.join(map(str, laps))} laps; merge runs "
              "of one route length", file=sys.stderr)
        return 2
    ordered = sorted(cases.values(), key=lambda c: (list(CONDITIONS).index(c.condition), c.seed))
    summary = summarize(ordered)
    summary["laps"] = laps[0] if laps else 1
    table = discovery_mc_markdown(summary)
    for cond in CONDITIONS:
        seeds = [c.seed for c in ordered if c.condition == cond]
        if seeds:
            print(f"{cond}: {len(seeds)} seeds {seeds[0]}..{seeds[-1]}")
    print(table)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        atomic_write_json(out / "discovery_mc.json",
                          {"summary": summary, "merged_from": [str(p) for p in paths],
                           "cases": [c.to_json() for c in ordered]})
        (out / "discovery_mc.md").write_text("# Effect discovery Monte Carlo\n\n" + table + "\n")
        print(f"written to {out}")
    return 0


def merge_flightgen(paths: list[Path], out: Path | None) -> int:
    """``--generator flightgen --merge``: summarise several flightgen runs' cases
    (cases.jsonl or discovery_mc_flightgen.json) together, a later file's case replacing
    an earlier one of the same condition, log rate and seed; print the tables and, with
    ``out``, write them there. Returns the exit code."""
    cases: dict[tuple[str, int, int], fgmc.FlightgenCase] = {}
    for p in paths:
        try:
            read = fgmc.read_cases(p)
        except (OSError, ValueError, KeyError, TypeError) as exc:
            print(f"error: {p}: cannot read a flightgen Monte Carlo's cases.jsonl or "
                  f"discovery_mc_flightgen.json ({type(exc).__name__}: {exc})", file=sys.stderr)
            return 2
        for case in read:
            cases[(case.condition, case.log_rate, case.seed)] = case
    ordered = sorted(cases.values(), key=lambda c: (c.log_rate,
                                                    fgmc.FG_CONDITIONS.index(c.condition), c.seed))
    rows = fgmc.summarize(ordered)
    table = flightgen_mc_markdown(rows)
    for rate in fgmc.LOG_RATES:
        for cond in fgmc.FG_CONDITIONS:
            seeds = [c.seed for c in ordered if c.condition == cond and c.log_rate == rate]
            if seeds:
                print(f"{rate} Hz {cond}: {len(seeds)} seeds {seeds[0]}..{seeds[-1]}")
    print(table)
    if out is not None:
        if (code := output_problem(out, directory=True)) is not None:
            return code
        out.mkdir(parents=True, exist_ok=True)
        _write_flightgen(out, rows, table, ordered, {"merged_from": [str(p) for p in paths]})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
