"""``python -m pinquad.yaw``: what the yaw torque model lacks on the measured Crazyflie
flights, candidate by candidate (``pinquad.realdata.yaw_candidates``): each fitted on some
flights, judged on the others."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from pinquad.cli.common import check_band
from pinquad.core.vehicle_file import load_vehicle
from pinquad.io.datadir import missing_data_hint
from pinquad.io.logs import LogFormatError
from pinquad.realdata.dataset import flights_dir, stand_dir
from pinquad.realdata.thrust import thrust_coefficient
from pinquad.realdata.yaw_candidates import (
    BAND,
    DT,
    FIT_FLIGHTS,
    GAIN_BANDS,
    HELD_OUT_FLIGHTS,
    INERTIA_BAND,
    YawStudy,
    geometric_rotor_inertia,
    rotor_parts,
    tilt_offset,
    yaw_signals,
    yaw_study,
)


def format_study(study: YawStudy, reference_izz: float) -> list[str]:
    """The candidate table and the per-flight lines, as printed."""
    held, fit = study.held_out, study.fit
    bands = " / ".join(f"{lo:g}-{hi:g}" for lo, hi in GAIN_BANDS)
    lines = [
        f"| candidate | J_r [e-9 kg m^2] | offset [ms] | D [e-7 N m s] | kappa | nu [1/V] | "
        f"leak x / y | "
        f"fit share | held-out share {' / '.join(held)} | |H| spread (max/min) "
        f"{' / '.join(held)} | I_zz {INERTIA_BAND[0]:g}-{INERTIA_BAND[1]:g} Hz "
        f"{' / '.join(held)} [e-6] |",
        "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in study.results:
        p = r.params
        free = set(r.candidate.free)

        def mark(i: int, text: str, free: set[int] = free) -> str:
            return f"**{text}**" if i in free else text

        lines.append(
            f"| {r.candidate.name} | {mark(0, f'{1e9 * p[0]:.1f}')} | "
            f"{mark(1, f'{1e3 * p[1]:+.2f}')} | {mark(2, f'{1e7 * p[2]:.2f}')} | "
            f"{mark(3, f'{p[3]:+.2f}')} | {mark(4, f'{p[4]:+.2f}')} | "
            f"{mark(5, f'{p[5]:+.3f}')} / {mark(6, f'{p[6]:+.3f}')} | {r.fit_share:.3f} | "
            + " / ".join(f"{r.held_out[n]:.3f}" for n in held) + " | "
            + " / ".join(f"{r.responses[n].spread:.2f}" for n in held) + " | "
            + " / ".join(f"{1e6 * r.responses[n].inertia:.1f}" for n in held) + " |")
    lines += ["", "bold: fitted on the fit flights (within the physical domain "
              "yaw_candidates.DOMAIN); the rest fixed", ""]
    lines.append(f"apparent yaw inertia |H| [e-6 kg m^2] in the bands {bands} Hz and the "
                 f"phase of H [deg] (> 0: the modelled torque leads), every flight "
                 f"(published I_zz {1e6 * reference_izz:.2f}):")
    for r in study.results:
        lines.append(f"- {r.candidate.name} ({r.candidate.predicts}):")
        for n in (*held, *fit):
            resp = r.responses[n]
            role = "held out" if n in held else "fit"
            lines.append(
                f"  - {n} ({role}): |H| " + " / ".join(f"{1e6 * g:.1f}" for g in resp.gain)
                + ", phase " + " / ".join(f"{x:+.0f}" for x in resp.phase)
                + f", I_zz {1e6 * resp.inertia:.1f} (reverse regression "
                f"{1e6 * resp.inertia_reverse:.1f}), held-out share {r.held_out[n]:.3f}")
    return lines


def _tilt_offsets(paths: Sequence[Path]) -> int:
    """Print :func:`tilt_offset` of each log alone; exit code 2 on a log it cannot read."""
    spec = load_vehicle("crazyflie21")
    print("log | seconds | roll / pitch time offset [ms] | unexplained roll / pitch share")
    for path in paths:
        try:
            sig = yaw_signals(path, spec.actuators.kf, spec.actuators.yaw_ratio, spec.spin,
                              spec.faults.flight_rpm or 10000.0, spec.arm)
        except (LogFormatError, ValueError, FileNotFoundError) as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        delta, shares = tilt_offset([sig])
        print(f"{path.name} | {sig.seconds:.1f} | {1e3 * delta:+.2f} | "
              f"{shares[0, 0]:.3f} / {shares[0, 1]:.3f}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m pinquad.yaw",
        description="Candidate effects of the yaw torque on the measured Crazyflie flights "
                    "(rotor inertia, a time offset between rotor speeds and gyro, yaw "
                    "damping, a torque ratio changing with speed or battery), each fitted on "
                    "the fit flights and judged on the held-out ones: unexplained share of "
                    "the band-passed yaw acceleration on held-out blocks, flatness of the "
                    "apparent yaw inertia.")
    p.add_argument("--data", type=Path, default=None,
                   help="Crazyflie data directory (default: $PINQUAD_CRAZYFLIE_DATA, else "
                        "../shared/data/crazyflie next to the repository)")
    p.add_argument("--fit", nargs="+", default=list(FIT_FLIGHTS), metavar="LOG",
                   help=f"flights the candidates are fitted on (default: {' '.join(FIT_FLIGHTS)})")
    p.add_argument("--held-out", nargs="+", default=list(HELD_OUT_FLIGHTS), metavar="LOG",
                   help="flights they are judged on (default: "
                        f"{' '.join(HELD_OUT_FLIGHTS)})")
    p.add_argument("--band", type=float, nargs=2, default=list(BAND), metavar=("LO", "HI"),
                   help=f"band [Hz] of the fit and the held-out share (default {BAND[0]:g} "
                        f"{BAND[1]:g})")
    p.add_argument("--tilt-offset", nargs="+", type=Path, default=None, metavar="LOG",
                   help="instead, print the roll / pitch time offset between rotor speeds and "
                        "gyro of each micro-SD log given by its path (any X-layout vehicle "
                        "logging rpm.m1-m4; the offset does not depend on kf)")
    args = p.parse_args(argv)
    check_band(p, args.band)
    if not 0.0 < args.band[0] < args.band[1] < 0.45 / DT:
        p.error(f"--band LO HI: expected 0 < LO < HI < {0.45 / DT:g} Hz (a band-pass on the "
                f"{1 / DT:g} Hz grid); got {args.band[0]:g} {args.band[1]:g}")
    if args.tilt_offset is not None:
        return _tilt_offsets(args.tilt_offset)
    both = sorted(set(args.fit) & set(args.held_out))
    if both:
        print(f"error: --fit and --held-out: flights both fitted on and held out: "
              f"{', '.join(both)}; expected two disjoint sets", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    spec = load_vehicle("crazyflie21")
    act = spec.actuators
    flights = flights_dir(args.data)
    if not flights.is_dir():
        print(f"error: {flights}: no such directory; expected the Crazyflie flight logs: "
              f"{missing_data_hint()}", file=sys.stderr)
        return 2
    try:
        kf = thrust_coefficient(stand_dir(args.data))
        signals = {n: yaw_signals(flights / n, kf.kf, act.yaw_ratio, spec.spin,
                                  spec.faults.flight_rpm or 10000.0, spec.arm)
                   for n in dict.fromkeys([*args.fit, *args.held_out])}
        if spec.aero.rotor_radius is None:
            raise ValueError(f"{spec.source}: no [aero] rotor_radius; the rotor inertia from "
                             "the rotor's geometry needs the propeller's radius")
        parts = rotor_parts(spec.aero.rotor_radius)
        jr, jr_se = geometric_rotor_inertia(parts)
        study = yaw_study(signals, jr, args.fit, args.held_out, tuple(args.band))
    except (LogFormatError, ValueError, FileNotFoundError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"yaw torque candidates: fitted on {', '.join(study.fit)}; judged on "
          f"{', '.join(study.held_out)}; band {study.band[0]:g}-{study.band[1]:g} Hz; kf "
          f"{kf.kf:.4g} "
          f"N/(rad/s)^2, yaw ratio {act.yaw_ratio:g} m\n")
    print(f"rotor inertia from geometry: J_r = {1e9 * jr:.1f} ± {1e9 * jr_se:.1f} e-9 kg m^2 "
          "(one standard uncertainty), the sum of")
    for part in parts:
        print(f"- {part.name}: {part.shape:g} x {1e3 * part.mass:.2g} g x "
              f"({1e3 * part.radius:g} mm)^2 = {1e9 * part.inertia:.1f} ± "
              f"{1e9 * part.inertia_se:.1f} e-9 ({part.source})")
    shares = ", ".join(f"{n} {a:.3f} / {b:.3f}" for n, (a, b) in
                       zip(study.fit, study.tilt_shares, strict=True))
    print(f"\ntime offset between rotor speeds and gyro on ROLL and PITCH (no rotor inertia "
          f"there): the rotor torque shifted by {1e3 * study.tilt_delta:+.2f} ms fits the fit "
          f"flights best (unexplained roll / pitch share: {shares}); the held-out flights "
          f"alone give {1e3 * study.tilt_held_out:+.2f} ms\n")
    for line in format_study(study, float(np.asarray(spec.reference.inertia)[2])):
        print(line)
    print(f"\n{len(signals)} logs in {time.perf_counter() - t0:.0f} s")
    return 0
