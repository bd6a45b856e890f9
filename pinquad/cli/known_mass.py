"""``python -m pinquad.offline --log FILE --mass KG --vehicle FILE [--band LO HI]``:
known-mass identification of a PX4 log by regression (``pinquad.identification.known_mass``)
and by EM beside it (``pinquad.identification.known_mass_em``); --band: the torque band of
both, default 0.3-2 Hz. Exit 0 when every estimate either route can give is trusted, 3
when one is not (report written), 2 on bad input (nothing written)."""

from __future__ import annotations

import argparse
import time

from pinquad.core.actuator_curve import read_curve_vehicle
from pinquad.identification.known_mass import KnownMassSettings, identify_known_mass
from pinquad.identification.known_mass_em import identify_known_mass_em
from pinquad.io.read import read_command_log
from pinquad.io.runs import RunWriter, atomic_write_bytes, atomic_write_json, new_run_dir
from pinquad.report.known_mass import headline_trusted, known_mass_report, known_mass_table

UNTRUSTED = 3


def mass_of(text: str, vehicle_mass: float | None) -> float:
    """--mass: a number [kg], or ``file`` for the vehicle file's [reference] mass."""
    if text == "file":
        if vehicle_mass is None:
            raise ValueError("--mass file: the vehicle file has no [reference] mass")
        return vehicle_mass
    try:
        mass = float(text)
    except ValueError:
        raise ValueError(f"--mass {text!r}: expected a mass in kg or 'file'") from None
    if not 0.0 < mass < 100.0:
        raise ValueError(f"--mass {text}: expected a mass in kg between 0 and 100")
    return mass


def run_known_mass(args: argparse.Namespace) -> int:
    """Read the log and the vehicle (rotor positions), identify, print, write the run.
    Raises ValueError (LogFormatError, VehicleFileError) naming the file on bad input."""
    if args.vehicle is None:
        raise ValueError("--mass needs the rotor positions: --vehicle FILE (a vehicle file "
                         ".toml with [[rotor]] tables, or a data-driven-dynamics .yaml)")
    vehicle = read_curve_vehicle(args.vehicle)  # VehicleFileError: a ValueError
    mass = mass_of(args.mass, vehicle.spec.reference.mass)
    writer = RunWriter(args.out or new_run_dir("log"))  # --out checked before any work
    t0 = time.perf_counter()
    flight = read_command_log(args.log)
    print(f"pinquad offline --log {args.log} --mass {mass:g}: known-mass regression and EM, "
          f"{flight.log.n} rows of {flight.log.dt * 1e3:.0f} ms, {flight.n_motors} motors")
    settings = KnownMassSettings(**({} if args.band is None else {"band": tuple(args.band)}))
    result = identify_known_mass(flight, mass, vehicle.spec.positions, vehicle.spec.spin,
                                 vehicle.curve, settings)
    em = identify_known_mass_em(flight, mass, vehicle.spec.positions, vehicle.spec.spin,
                                result, vehicle.curve, settings)
    seconds = time.perf_counter() - t0
    table = known_mass_table(result, vehicle, em)
    print()
    print(table)
    with writer:
        atomic_write_json(writer.path("report.json"),
                          known_mass_report(result, str(args.log), vehicle, seconds, em))
        atomic_write_bytes(writer.path("report.md"), f"```\n{table}\n```\n".encode())
        final = writer.publish()
    print(f"\n{seconds:.1f} s; run written to {final}")
    return 0 if headline_trusted(result, em) else UNTRUSTED
