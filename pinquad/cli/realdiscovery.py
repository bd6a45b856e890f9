"""``python -m pinquad.realdiscovery``: effect discovery on the measured Crazyflie flights,
trained on some logs and tested on others: each log read, checked and fitted by the
pipeline (``pinquad.experiments.realdiscovery.flight_fit``), the splits by
``pinquad.experiments.realdiscovery``, the table by ``pinquad.report.realdiscovery``."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from pinquad.cli.common import output_problem
from pinquad.experiments.realdiscovery import POOLED, SPLITS, FlightFit, flight_fit, run_split
from pinquad.io.datadir import default_data_dir, missing_data_hint
from pinquad.io.logs import LogFormatError, vehicle_file_named
from pinquad.io.runs import atomic_write_json
from pinquad.report.realdiscovery import realdiscovery_markdown


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m pinquad.realdiscovery``."""
    p = argparse.ArgumentParser(prog="python -m pinquad.realdiscovery",
                                description="Effect discovery on the measured Crazyflie flights: "
                                            "train on some logs, test on others.")
    p.add_argument("--data", type=Path, default=None,
                   help="imrc_brushed/ directory or the Crazyflie data directory (default: "
                        "$PINQUAD_CRAZYFLIE_DATA, else ../shared/data/crazyflie next to the "
                        "repository, else the copy `python -m pinquad.data fetch crazyflie` "
                        "downloads)")
    p.add_argument("--splits", nargs="*", default=list(SPLITS), choices=list(SPLITS))
    p.add_argument("--vehicle", default="crazyflie21", metavar="NAME|FILE",
                   help="the logs' vehicle: crazyflie21 (default, the IMRC Lab splits) or a "
                        "vehicle file (.toml, docs/vehicles.md); with a file give the split: "
                        "--train, --test, --effect, logs in --data")
    p.add_argument("--train", nargs="+", metavar="LOG", help="training logs of a split of "
                   "your own (names in --data)")
    p.add_argument("--test", nargs="+", metavar="LOG", help="its test logs")
    p.add_argument("--effect", choices=list(POOLED), default="drag",
                   help="the effect that split is about")
    p.add_argument("--out", type=Path, default=None, help="write realdiscovery.json/.md here")
    return p


def main(argv: list[str] | None = None) -> int:
    """Run the splits, print the table (and the training mass with the pooled effects),
    write realdiscovery.json/.md to ``--out`` if given. Returns the exit code."""
    args = build_parser().parse_args(argv)
    data = args.data or default_data_dir() / "imrc_brushed"
    if (data / "imrc_brushed").is_dir():
        data = data / "imrc_brushed"
    vehicle = args.vehicle
    if vehicle != "crazyflie21":
        try:
            vehicle = vehicle_file_named(vehicle, Path.cwd(), "--vehicle")
        except LogFormatError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
    if (args.train is None) != (args.test is None) or (
            vehicle != "crazyflie21" and args.train is None):
        print("error: a split of your own needs both --train and --test (and a vehicle file "
              "needs one: the built-in splits are the IMRC Lab Crazyflie's)", file=sys.stderr)
        return 2
    splits = ({"custom": (tuple(args.train), tuple(args.test), args.effect)}
              if args.train is not None else {s: SPLITS[s] for s in args.splits})
    if not data.is_dir():
        print(f"error: {data}: no such directory; expected the Crazyflie flight logs "
              f"(imrc_brushed/): {missing_data_hint()}", file=sys.stderr)
        return 2
    if (code := output_problem(args.out, directory=True)) is not None:
        return code
    t0 = time.perf_counter()
    cache: dict[str, FlightFit] = {}
    results = {}
    try:
        for s, split in splits.items():
            print(f"split {s}: train {', '.join(split[0])}; test {', '.join(split[1])}; "
                  f"effect {split[2]}",
                  flush=True)
            for n in (*split[0], *split[1]):
                if n not in cache:
                    cache[n] = flight_fit(data / n, vehicle)
            results[s] = run_split(s, cache, split)
    except (FileNotFoundError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    text = realdiscovery_markdown(results)
    print(text)
    for s, r in results.items():
        if "refit" in r:
            print(f"{s}: training mass {1e3 * r['base']['mass']:.2f} g -> {1e3 * r['refit']['mass']:.2f} g "
                  f"with {', '.join(r['pooled_effects'])}")
    print(f"{time.perf_counter() - t0:.0f} s")
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        atomic_write_json(args.out / "realdiscovery.json", results)
        (args.out / "realdiscovery.md").write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
