"""``python -m pinquad.flight``: the simulated world on its own (``pinquad.experiments.flight``:
waypoint tracking and the sensor-A EKF beside the paper's Table I, with NEES)."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from tqdm import tqdm

from pinquad.cli.common import add_backend_arguments, backend_from_args, output_problem
from pinquad.cli.help import HelpFormatter, positive_int
from pinquad.core.execution import BackendError, open_executor
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
    add_backend_arguments(p, os.cpu_count() or 1, "flights")
    p.add_argument("--out", type=Path, help="also write the figures as JSON to this file")
    args = p.parse_args(argv)
    if (code := output_problem(args.out, directory=False)) is not None:
        return code
    seeds = range(args.seed, args.seed + args.seeds)
    jobs = ([("paper", s, "tuned") for s in seeds] + [("crazyflie21", s, "tuned") for s in seeds]
            + [("paper", s, "paper") for s in seeds])
    try:
        with open_executor(backend_from_args(args), len(jobs)) as pool:
            runs = list(tqdm(pool.map(fly, jobs), total=len(jobs), desc="flights",
                             file=sys.stderr))
    except BackendError as exc:  # raised before any flight
        print(f"error: {exc}", file=sys.stderr)
        return 2
    text, out = flight_tables(runs, seeds)
    print(text)
    if args.out:
        atomic_write_json(args.out, out)
        print(f"\nwritten {args.out}")
    return 0
