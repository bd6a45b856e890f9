"""Flights that take off, strike the floor twice and land, with no contact column in
the log (floor contact from the data; docs/trust.md). Each flightgen flight
goes CSV -> the pipeline of ``offline --log`` (``pinquad.pipeline.single.run``: identify,
then discovery with its null calibration; regressor M-step, at most 100 E-steps); it
prints the contact transitions found against the truth and what discovery selects.

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
from pinquad.pipeline.identify import LogOptions
from pinquad.pipeline.single import PipelineOptions, read, run

SEEDS = (1, 2, 3, 4)
RATE = 100
OPTIONS = PipelineOptions(identification=LogOptions(msteps=("regressor",), max_iterations=100,
                                                    information=False))


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
            log = read(path)
            piped = run(log, OPTIONS)
            result, outcome = piped.identified, piped.outcome
            assert outcome is not None  # a regressor fit, discovery asked for: always run
            truth = true_contact_transitions(flight, result.obs.n)
            found = found_contact_transitions(log)
            selected = outcome.result.selected if outcome.result is not None else outcome.error
            print(f"| {seed} | {int(truth.sum())} | {int((found & truth).sum())} | "
                  f"{int((truth & ~found).sum())} | {int((found & ~truth).sum())} | "
                  f"{', '.join(selected) or 'none'} | {result.runs[0].mass * 1e3:.2f} |")


if __name__ == "__main__":
    main()
