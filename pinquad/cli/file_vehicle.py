"""``python -m pinquad.offline --vehicle FILE.toml [--cycles N] [--seed S]``: the vehicle
of a file flown in the simulated world, logged with rotor speeds and identified from its
log as a user's log is (``pinquad.experiments.vehicle_file_mc``), over seeded cycles.

Prints the relative mass and inertia errors of each cycle, their RMS and worst value,
and how many cycles meet the bounds of the paper's offline experiment as pinquad meets
them; the run directory holds each cycle's log (``logs/seed_<S>.csv`` and its sidecar,
which names the vehicle file: ``python -m pinquad.offline --log`` reads it again),
``table.md`` and ``report.json``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from pinquad.core.paper_results import OFFLINE_INERTIA_BOUND, OFFLINE_MASS_BOUND
from pinquad.core.vehicle_file import VehicleFileError, load_vehicle
from pinquad.experiments.vehicle_file_mc import FILE_VEHICLE_BAND, cycle_lines, rms_errors, vehicle_file_cycle
from pinquad.io.runs import RunWriter, atomic_write_bytes, atomic_write_json, new_run_dir
from pinquad.pipeline.identify import LogOptions


def run_file_vehicle(args: argparse.Namespace) -> int:
    """Fly and identify the vehicle file ``args.vehicle`` over ``args.cycles`` seeds
    (``args.seed`` .. ``args.seed + cycles - 1``), one after the other. Raises
    ValueError (a bad file) before any work."""
    try:
        spec = load_vehicle(str(Path(args.vehicle).expanduser().resolve()))
    except VehicleFileError as exc:
        raise ValueError(str(exc)) from None
    if spec.actuators is None:
        raise ValueError(f"{spec.source}: no [actuators] table (kf, kf_se, yaw_ratio): the "
                         "simulated flight cannot be logged with rotor speeds")
    band = tuple(args.band) if args.band is not None else FILE_VEHICLE_BAND
    options = LogOptions(msteps=("regressor",), estep=args.estep, band=band,
                         max_iterations=args.max_iterations or 100,
                         information=not args.no_information)
    writer = RunWriter(args.out or new_run_dir("vehicle"))
    seeds = list(range(args.seed, args.seed + args.cycles))
    print(f"pinquad offline --vehicle {args.vehicle}: {args.cycles} cycle(s), seeds "
          f"{seeds[0]}..{seeds[-1]}; the paper's scenario flown with sensor B, logged with "
          f"rotor speeds, identified from the CSV log (regressor M-step, torque band "
          f"{band[0]:g}-{band[1]:g} Hz, E-step {args.estep})")
    t0 = time.perf_counter()
    with writer:
        cycles = []
        for seed in seeds:
            cycle = vehicle_file_cycle(spec, seed, writer.path(f"logs/seed_{seed}.csv"),
                                       options=options)
            e = 100.0 * cycle.rel_error
            print(f"  seed {seed}: mass {e[0]:+.3f} %, inertia {e[1]:+.2f} / {e[2]:+.2f} / "
                  f"{e[3]:+.2f} % ({time.perf_counter() - t0:.0f} s)", flush=True)
            cycles.append(cycle)
        lines = cycle_lines(spec, cycles)
        print()
        print("\n".join(lines))
        atomic_write_bytes(writer.path("table.md"), ("\n".join(lines) + "\n").encode())
        atomic_write_json(writer.path("report.json"), {
            "schema": "pinquad.report/1",
            "source": {"kind": "simulation", "vehicle": str(spec.source), "sensor": "B",
                       "estep": args.estep, "actuation": "rotor speeds", "band_hz": list(band)},
            "truth": {"mass": float(spec.mass), "inertia": spec.inertia.tolist()},
            "bounds": {"mass_rel": OFFLINE_MASS_BOUND, "inertia_rel": OFFLINE_INERTIA_BOUND},
            "rms_rel_error": dict(zip(("mass", "Ixx", "Iyy", "Izz"),
                                      rms_errors(cycles).tolist(), strict=True)),
            "cycles": [{"seed": c.seed, "log": f"logs/{c.log.name}",
                        "estimates": {"mass": float(c.estimate[0]),
                                      "inertia_diag": c.estimate[1:].tolist(),
                                      "stderr": {"mass": float(c.stderr[0]),
                                                 "inertia_diag": c.stderr[1:].tolist()},
                                      "verdict": c.verdict},
                        "rel_error": c.rel_error.tolist(), "within_bounds": c.within_bounds,
                        "em": {"e_steps": c.e_steps, "converged": c.converged},
                        "flight": {"max_miss_m": c.max_miss, "crashed": c.crashed}}
                       for c in cycles]})
        final = writer.publish()
    print(f"\n{time.perf_counter() - t0:.0f} s; run written to {final} (each cycle's log "
          f"in logs/: python -m pinquad.offline --log {final}/logs/seed_{seeds[0]}.csv "
          f"--band {band[0]:g} {band[1]:g} identifies it again)")
    return 0
