"""``python -m pinquad.flight``: the simulated world on its own (``pinquad.experiments.flight``:
waypoint tracking and the sensor-A EKF beside the paper's Table I, with NEES)."""

from __future__ import annotations

import argparse
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from tqdm import tqdm

from pinquad.cli.common import output_problem
from pinquad.cli.help import HelpFormatter, positive_int
from pinquad.experiments import flight
from pinquad.experiments.flight import fly
from pinquad.io.runs import atomic_write_json
from pinquad.report.flight import flight_tables


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m pinquad.flight",
                                description=flight.__doc__.split("\n\n")[1],
                                formatter_class=HelpFormatter)
    p.add_argument("--seeds", type=positive_int, default=20, help="seeded runs per configuration")
    p.add_argument("--seed", type=int, default=0, help="first seed")
    p.add_argument("--jobs", type=positive_int, default=os.cpu_count() or 1,
                   help="worker processes")
    p.add_argument("--out", type=Path, help="also write the figures as JSON to this file")
    args = p.parse_args(argv)
    if (code := output_problem(args.out, directory=False)) is not None:
        return code
    seeds = range(args.seed, args.seed + args.seeds)
    jobs = ([("paper", s, "tuned") for s in seeds] + [("crazyflie21", s, "tuned") for s in seeds]
            + [("paper", s, "paper") for s in seeds])
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        runs = list(tqdm(pool.map(fly, jobs), total=len(jobs), desc="flights", file=sys.stderr))
    text, out = flight_tables(runs, seeds)
    print(text)
    if args.out:
        atomic_write_json(args.out, out)
        print(f"\nwritten {args.out}")
    return 0
