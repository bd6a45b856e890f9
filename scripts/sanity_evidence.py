"""The correct-log side of the physical checks (docs/bad_input.md): what each physical sanity check of
``pinquad.io.sanity`` measures on every shipped real Crazyflie log and on the simulated
flights of the paper's offline experiment (the default ``python -m pinquad.offline``:
20 cycles x sensors A, B, C, its flight seeds), and whether any check fires.

    PYTHONPATH=$PWD python scripts/sanity_evidence.py [CYCLES]

CYCLES: simulated cycles per sensor (default 20; about 1.5 s per flight). Prints one
row per log and a summary; exits 1 if any check fires on any of them.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from pinquad.core.params import PAPER_VEHICLE
from pinquad.experiments.offline_mc import flight_seed
from pinquad.io.read import read_log
from pinquad.io.sanity import evidence, findings
from pinquad.sim.simulator import SimConfig, flight_log, simulate

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "crazyflie"


def _fmt(value: float | None, spec: str) -> str:
    return "-" if value is None else f"{value:{spec}}"


def _row(name: str, log) -> tuple[str, int]:
    ev = evidence(log)
    fired = findings(log)
    return (f"| {name} | {log.n} | {ev.dt * 1e3:.2f} | {_fmt(ev.gyro_ratio, '.3f')} | "
            f"{_fmt(ev.position_velocity_ratio, '.3f')} | {_fmt(ev.position_accel, '.2f')} | "
            f"{_fmt(ev.velocity_accel, '.2f')} | {_fmt(ev.specific_force, '.2f')} | "
            f"{_fmt(None if ev.implied_mass is None else ev.implied_mass * 1e3, '.1f')} | "
            f"{'; '.join(f.check for f in fired) or 'none'} |", len(fired))


def main(argv: list[str]) -> int:
    cycles = int(argv[0]) if argv else 20
    print("| log | rows | dt [ms] | gyro / attitude | position / velocity | "
          "99 % accel from pos [m/s^2] | from vel | median abs(acc) [m/s^2] | "
          "mass from thrust [g] | checks fired |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    fired = 0
    real = sorted(p for d in ("imrc_brushed", "imrc_brushless") for p in (DATA / d).iterdir()
                  if p.suffix != ".txt")
    for path in real:
        line, n = _row(path.name, read_log(path))
        print(line)
        fired += n
    for sensor in "ABC":
        for cycle in range(cycles):
            seed = flight_seed(0, sensor, cycle)
            log = flight_log(simulate(SimConfig(vehicle=PAPER_VEHICLE, sensor=sensor),
                                      np.random.default_rng(seed)))
            line, n = _row(f"paper {sensor} seed {seed}", log)
            print(line)
            fired += n
    total = len(real) + 3 * cycles
    print(f"\n{len(real)} real logs + {3 * cycles} simulated flights: {fired} check(s) fired "
          f"in {total} logs")
    return 1 if fired else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
