"""Flights that take off, strike the floor twice and land, with no contact column in
the log (floor contact from the data; docs/trust.md). Each flightgen flight
goes CSV -> ``offline --log``'s path (identify_log, then discovery with its null
calibration); it prints the contact transitions found against the truth and what
discovery selects.

    PYTHONPATH=$PWD python scripts/floor_strikes.py      (about 3 minutes on 2 cores)
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from flightgen import FlightSpec, generate, write_csv
from pinquad.experiments.discovery_mc_flightgen import (
    found_contact_transitions,
    true_contact_transitions,
)
from pinquad.io.read import read_log
from pinquad.pipeline.discover import run_discovery
from pinquad.pipeline.identify import LogOptions, identify_log

SEEDS = (1, 2, 3, 4)
RATE = 100


def main() -> None:
    print(f"flightgen, {RATE} Hz, 30 s minimum-snap, take-off, 2 floor strikes, landing, "
          f"no contact column; seeds {SEEDS}")
    print("| seed | true contact transitions | found | missed | found off contact | "
          "selected (null-calibrated) | mass [g] |")
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for seed in SEEDS:
            spec = FlightSpec(duration=30, trajectory="minsnap", log_rate=RATE, seed=seed,
                              start_on_floor=True, land=True, floor_strikes=2)
            flight = generate(spec)
            path = write_csv(flight, Path(tmp) / f"strikes_{seed}.csv")
            log = read_log(path)
            result = identify_log(log, LogOptions(msteps=("regressor",), information=False))
            truth = true_contact_transitions(flight, result.obs.n)
            found = found_contact_transitions(log)
            outcome = run_discovery(result)
            selected = outcome.result.selected if outcome.result is not None else outcome.error
            print(f"| {seed} | {int(truth.sum())} | {int((found & truth).sum())} | "
                  f"{int((truth & ~found).sum())} | {int((found & ~truth).sum())} | "
                  f"{', '.join(selected) or 'none'} | {result.runs[0].mass * 1e3:.2f} |")


if __name__ == "__main__":
    main()
