"""``python -m pinquad.discovery``: the seeded Monte Carlo of effect discovery through the
CSV ``--log`` path (``pinquad.experiments.discovery_mc``), or ``--merge`` of earlier runs'
cases; tables by ``pinquad.report.discovery_mc``."""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from tqdm import tqdm

from pinquad.cli.common import output_problem
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


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m pinquad.discovery``."""
    p = argparse.ArgumentParser(prog="python -m pinquad.discovery",
                                description="Seeded Monte Carlo of effect discovery through "
                                            "the CSV --log path (module pinquad.discovery_mc).")
    p.add_argument("--seeds", type=int, default=20, help="seeds per condition")
    p.add_argument("--base-seed", type=int, default=0, help="base seed")
    p.add_argument("--conditions", nargs="*", default=list(CONDITIONS), choices=list(CONDITIONS))
    p.add_argument("--jobs", type=int, default=1, help="worker processes")
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
        return merge(args.merge, args.out)
    if args.seeds < 1 or args.laps < 1:
        print("error: --seeds and --laps must be at least 1", file=sys.stderr)
        return 2
    out = args.out or new_run_dir("discovery-mc")
    if (code := output_problem(out, directory=True)) is not None:
        return code
    out.mkdir(parents=True, exist_ok=True)
    jobs = [(c, case_seed(args.base_seed, c, i)) for c in args.conditions
            for i in range(args.start_index, args.start_index + args.seeds)]
    print(f"discovery Monte Carlo: {len(args.conditions)} condition(s) x {args.seeds} seeds, "
          f"base seed {args.base_seed} (seed = base*100000 + condition*1000 + i), {args.laps} "
          f"lap(s) of the route, {args.jobs} worker(s)")
    t0 = time.perf_counter()
    cases: list[CaseResult] = []
    with tempfile.TemporaryDirectory(prefix="pinquad-dmc-") as tmp:
        work = [CaseJob(c, s, tmp, args.laps) for c, s in jobs]
        for res in tqdm(run_cases(work, args.jobs), total=len(work), unit="flight",
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


def merge(paths: list[Path], out: Path | None) -> int:
    """``--merge``: summarise several runs' cases together (later files win on duplicates);
    print the tables and, with ``out``, write them there. Returns the exit code."""
    cases: dict[tuple[str, int], CaseResult] = {}
    seen_laps: set[int] = set()
    for p in paths:
        try:
            read = read_cases(p)
        except (OSError, ValueError) as exc:
            print(f"error: {p}: cannot read a discovery_mc.json ({exc})", file=sys.stderr)
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


if __name__ == "__main__":
    raise SystemExit(main())
