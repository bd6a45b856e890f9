"""The correct-log side of the declaration checks (``pinquad.io.declaration_check``,
docs/bad_input.md): what each statistic measures on correct logs with correct
declarations, its weakest value against its threshold, and whether any check fires.

* the 24 shared IMRC micro-SD logs with their vehicle files (jana*:
  ``pinquad/data/crazyflie21.toml`` given as a file, eckart*: ``docs/vehicles/
  cf21_brushless.toml``): the torque-axis correlations and the hover balance against the
  file's reference mass;
* jana00 exported as pinquad's Parquet log and written in each other logger's convention
  with that convention declared (``pinquad.io.foreign.write_foreign``): the declared
  attitude, frame, rotor-speed and motor-order tests;
* the six Neural-Swarm flights read natively, and the two Parrot-frame flights with
  ``docs/vehicles/cf21_parrot_frame.toml``: the model-free mass's sign.

    PYTHONPATH=$PWD python scripts/declaration_evidence.py

Prints one row per log, the margins, and exits 1 if any check fires.
"""

from __future__ import annotations

import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from pinquad.core.conventions import rotation_from_euler
from pinquad.io.conventions_check import (
    agreement,
    hover_thrust_ratio,
    rotations,
    rotor_model,
    torque_correlations,
)
from pinquad.io.declaration_check import (
    AXIS_BLOCKS_NEGATIVE,
    AXIS_CORRELATION,
    MASS_FILE_FACTOR,
    axis_correlations,
    model_free_mass,
    upright,
)
from pinquad.io.declared import Conventions
from pinquad.io.foreign import write_foreign
from pinquad.io.logs import read_table, write_log
from pinquad.io.read import read_log, with_vehicle
from pinquad.io.sanity import findings

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
CF = DATA / "crazyflie"
DECLARED = (Conventions(quaternion_order="xyzw"), Conventions(frame="NED/FRD"),
            Conventions(quaternion_rotation="world_to_body"), Conventions(rotor_speed="rad/s"),
            Conventions(motor_order=(2, 3, 4, 1)),
            Conventions(frame="NED/FRD", quaternion_order="xyzw", motor_order=(4, 3, 2, 1)))


def _fired(log) -> str:
    return "; ".join(f.check for f in findings(log)) or "none"


def main() -> int:
    fired = 0
    axes, negatives, ratios, masses = [], [], [], []
    print("| log | vehicle file | roll, pitch, yaw correlation | negative blocks | hover / "
          "reference mass | checks fired |\n|---|---|---|---|---|---|")
    pairs = [(p, ROOT / "pinquad" / "data" / "crazyflie21.toml")
             for p in sorted((CF / "imrc_brushed").glob("jana*"))]
    pairs += [(p, ROOT / "docs" / "vehicles" / "cf21_brushless.toml")
              for p in sorted((CF / "imrc_brushless").glob("eckart*"))]
    for path, vehicle in pairs:
        log = with_vehicle(read_log(path), str(vehicle), ROOT, "evidence")
        spec = rotor_model(log)
        ev = axis_correlations(log, spec)
        mass = model_free_mass(log)
        ref = spec.reference.mass if spec.reference.mass is not None else spec.mass
        words = _fired(log)
        fired += words != "none"
        if ev is not None:
            axes.append(ev.correlation)
            negatives.append(ev.negative_blocks)
        if mass is not None:
            ratios.append(mass / ref)
        print(f"| {path.name} | {vehicle.name} | "
              f"{'-' if ev is None else ', '.join(f'{c:.2f}' for c in ev.correlation)} | "
              f"{'-' if ev is None else ', '.join(str(n) for n in ev.negative_blocks)} | "
              f"{'-' if mass is None else f'{mass / ref:.3f}'} | {words} |")
    decl = []
    with tempfile.TemporaryDirectory() as tmp:
        clean = read_table(write_log(replace(read_log(CF / "imrc_brushed" / "jana00"),
                                             measured=None), Path(tmp) / "clean.parquet"))
        for k, conv in enumerate(DECLARED):
            log = read_table(write_foreign(clean, Path(tmp) / f"{k}.parquet", conv, True))
            rot = rotations(log.euler, rotation_from_euler)
            fit = agreement(log.t, rot, log.gyro)
            up = upright(log)
            spec = rotor_model(log)
            scores = torque_correlations(log, spec)
            ident = tuple(range(1, 5))
            margin = scores[ident] - max(v for p, v in scores.items() if p != ident)
            ratio = hover_thrust_ratio(log, spec)
            mass = model_free_mass(log)
            masses.append(mass)
            words = _fired(log)
            fired += words != "none"
            decl.append((fit, up, margin, ratio))
            print(f"| jana00 export, declared {conv.sidecar()} | - | gyro ratio {fit[0]:.3f} "
                  f"(R^2 {fit[1]:.2f}), acc z body {up.body:.2f} world {up.world:.2f} | "
                  f"numbering margin {margin:.2f} | hover thrust ratio {ratio:.2f}, "
                  f"model-free mass {mass * 1e3:.2f} g | {words} |")
    for path in sorted((DATA / "neural_swarm" / "flights").iterdir()):
        for vehicle in (None, ROOT / "docs" / "vehicles" / "cf21_parrot_frame.toml"):
            if vehicle is not None and "cf10" not in path.name:
                continue
            log = read_log(path)
            if vehicle is not None:
                log = with_vehicle(log, str(vehicle), ROOT, "evidence")
            mass = model_free_mass(log)
            if mass is not None:
                masses.append(mass)
            words = _fired(log)
            fired += words != "none"
            print(f"| {path.name} | {'-' if vehicle is None else vehicle.name} | - | - | "
                  f"model-free mass {'-' if mass is None else f'{mass * 1e3:.2f} g'} | {words} |")
    axes_a, neg_a = np.array(axes), np.array(negatives)
    print("\nmargins (weakest correct-log value against its threshold):")
    print(f"- torque axes: lowest correlation roll {axes_a[:, 0].min():.2f}, pitch "
          f"{axes_a[:, 1].min():.2f}, yaw {axes_a[:, 2].min():.2f} (fires below "
          f"-{AXIS_CORRELATION}); most negative blocks {neg_a.max(axis=0).tolist()} (fires at "
          f"{AXIS_BLOCKS_NEGATIVE} of 10); {len(axes)} logs decided")
    print(f"- hover / reference mass: {min(ratios):.3f} to {max(ratios):.3f} (fires outside "
          f"{1 / MASS_FILE_FACTOR:.3f} to {MASS_FILE_FACTOR}); {len(ratios)} logs decided")
    print(f"- model-free mass: smallest {min(masses) * 1e3:.2f} g (fires at <= 0)")
    fits = [d[0] for d in decl]
    print(f"- declared attitude: gyro ratio {min(f[0] for f in fits):.3f} to "
          f"{max(f[0] for f in fits):.3f} (0.5 to 2), R^2 >= {min(f[1] for f in fits):.2f} "
          f"(0.5); world z at least {min(d[1].world for d in decl):.2f}, body z at least "
          f"{min(d[1].body for d in decl):.2f} m/s^2 (fires below "
          f"{-0.5 * max(d[1].scale for d in decl):.2f})")
    print(f"- declared motor order: the declared numbering ahead by at least "
          f"{min(d[2] for d in decl):.2f} (fires when another leads by 0.2); hover thrust "
          f"ratio {min(d[3] for d in decl):.2f} to {max(d[3] for d in decl):.2f} (0.2 to 5)")
    total = len(pairs) + len(DECLARED) + 8
    print(f"\n{total} correct logs: {fired} check(s) fired")
    return 1 if fired else 0


if __name__ == "__main__":
    sys.exit(main())
