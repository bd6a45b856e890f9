"""``python -m pinquad.offline --log FILE [FILE ...] --mass KG --vehicle FILE [--band LO HI]
[--range LO HI ...] [--joint]``: known-mass identification of logs whose actuation is
motor commands, by regression (``pinquad.identification.known_mass``) and, for one PX4
log with attitude and velocity, by EM beside it (``pinquad.identification.known_mass_em``).
A Crazyflie micro-SD log is read as IMU-only (``pinquad.io.imu_log``) and fitted on its
flight segments or the --range rows; several logs with --joint: one fit of the vehicle,
printed beside each log's own. --band: the torque band, default 0.3-2 Hz. Exit 0 when
every estimate is trusted, 3 when one is not (report written), 2 on bad input (nothing
written)."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from pinquad.core.actuator_curve import read_curve_vehicle
from pinquad.identification.excitation import segments_of
from pinquad.identification.known_mass import (
    KnownMassResult,
    KnownMassSettings,
    identify_known_mass,
)
from pinquad.identification.known_mass_em import identify_known_mass_em
from pinquad.io.read import read_command_log
from pinquad.io.runs import RunWriter, atomic_write_bytes, atomic_write_json, new_run_dir
from pinquad.report.known_mass import (
    headline_trusted,
    joint_comparison,
    known_mass_report,
    known_mass_table,
)

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


def parse_ranges(ranges: list[list[str]] | None, n_logs: int
                 ) -> list[list[tuple[float, float]] | None]:
    """--range per log: pairs (lo, hi) [s, the log's clock], or None ('auto', or no
    --range). Raises ValueError on a malformed --range."""
    if ranges is None:
        return [None] * n_logs
    if len(ranges) != n_logs:
        raise ValueError(f"--range given {len(ranges)} times for {n_logs} --log; expected "
                         "one --range per log, in order ('auto' for a log's flight segments)")
    out: list[list[tuple[float, float]] | None] = []
    for words in ranges:
        if words == ["auto"]:
            out.append(None)
            continue
        try:
            values = [float(w) for w in words]
        except ValueError:
            raise ValueError(f"--range {' '.join(words)}: expected pairs LO HI of seconds "
                             "on the log's clock, or 'auto'") from None
        if len(values) % 2 or any(lo >= hi for lo, hi in zip(values[::2], values[1::2],
                                                              strict=True)):
            raise ValueError(f"--range {' '.join(words)}: expected pairs LO HI with LO < HI "
                             "[s on the log's clock]")
        out.append(list(zip(values[::2], values[1::2], strict=True)))
    return out


def run_known_mass(args: argparse.Namespace) -> int:
    """Read the logs and the vehicle (rotor positions), identify, print, write the run.
    Raises ValueError (LogFormatError, VehicleFileError) naming the file on bad input."""
    if args.vehicle is None:
        raise ValueError("--mass needs the rotor positions: --vehicle FILE (a vehicle file "
                         ".toml with [[rotor]] tables or [geometry], a shipped name such as "
                         "crazyflie21, or a data-driven-dynamics .yaml)")
    paths = [Path(p) for p in args.log]
    ranges = parse_ranges(args.range, len(paths))
    vehicle = read_curve_vehicle(args.vehicle)  # VehicleFileError: a ValueError
    mass = mass_of(args.mass, vehicle.spec.reference.mass)
    writer = RunWriter(args.out or new_run_dir("log"))  # --out checked before any work
    settings = KnownMassSettings(**({} if args.band is None else {"band": tuple(args.band)}))
    t0 = time.perf_counter()
    flights = [read_command_log(p) for p in paths]
    cut = [segments_of(f, r, settings.band) for f, r in zip(flights, ranges, strict=True)]
    pos, spin = vehicle.spec.positions, vehicle.spec.spin
    separate: list[KnownMassResult | str] = []
    for path, flight, (segs, excitation) in zip(paths, flights, cut, strict=True):
        print(f"pinquad offline --log {path} --mass {mass:g}: known-mass regression"
              f"{'' if flight.imu_only or len(paths) > 1 else ' and EM'}, "
              f"{sum(s.log.n for s in segs)} rows of {flight.log.dt * 1e3:.0f} ms in "
              f"{len(segs)} segment(s), {flight.n_motors} motors")
        if excitation is not None:
            print(excitation.text())
        try:
            separate.append(identify_known_mass(segs, mass, pos, spin, vehicle.curve,
                                                settings))
        except ValueError as exc:
            if len(paths) == 1:
                raise
            # a log too short for its own fit still takes part in the joint one
            separate.append(f"{path}: no fit of its own ({exc})")
    joint = None
    if len(paths) > 1:
        groups = [g for g, (segs, _) in enumerate(cut) for _ in segs]
        joint = identify_known_mass([s for segs, _ in cut for s in segs], mass, pos, spin,
                                    vehicle.curve, settings, groups)
    em = None
    single = joint is None and len(cut[0][0]) == 1 and not flights[0].imu_only
    if single:
        assert isinstance(headline_first := separate[0], KnownMassResult)
        em = identify_known_mass_em(cut[0][0][0], mass, pos, spin, headline_first, vehicle.curve,
                                    settings)
    seconds = time.perf_counter() - t0
    headline = joint if joint is not None else separate[0]
    assert isinstance(headline, KnownMassResult)
    blocks = []
    for path, result in zip(paths, separate, strict=True):
        head = f"--- {path} ---\n" if joint is not None else ""
        blocks.append(head + (result if isinstance(result, str) else
                              known_mass_table(result, vehicle, em if single else None)))
    if joint is not None:
        blocks.append(f"--- joint fit of {len(paths)} logs ---\n"
                      + known_mass_table(joint, vehicle)
                      + "\n\n" + joint_comparison([str(p) for p in paths], separate, joint))
    if not single:
        blocks.append("note: EM route not run: " + (
            "the log has no velocity or attitude (an IMU-only log): the E-step has no "
            "channel that observes the translational state" if flights[0].imu_only else
            "EM runs on one contiguous segment of one log"))
    table = "\n\n".join(blocks)
    print()
    print(table)
    excitations = [e for _, e in cut]
    with writer:
        atomic_write_json(writer.path("report.json"), known_mass_report(
            headline, " ".join(str(p) for p in paths), vehicle, seconds, em,
            separate=separate if joint is not None else None,
            segments=[[(s.log.meta.t_origin, s.log.meta.t_origin + float(s.log.t[-1]))
                       for s in segs] for segs, _ in cut],
            excitation=excitations))
        atomic_write_bytes(writer.path("report.md"), f"```\n{table}\n```\n".encode())
        final = writer.publish()
    print(f"\n{seconds:.1f} s; run written to {final}")
    return 0 if headline_trusted(headline, em) else UNTRUSTED
