"""A real IMRC flight written as other loggers write it: what pinquad does with each.

The flight (default jana00 of the shared IMRC brushed logs) is exported once as
pinquad's own Parquet log (its ~500 Hz rows with rotor speeds, ``write_log``) and
identified (regressor M-step, standard errors: the clean export). Each variant is then
written (``pinquad.io.foreign.write_foreign`` for the conventions) and run through the
read and identify steps of ``python -m pinquad.offline --log``'s pipeline
(``pinquad.pipeline.single``):

* a refusal prints ``exit 2`` and the message the command prints after ``error:``;
* an identification prints the largest change of mass, I_xx, I_yy, I_zz against the
  clean export, in the clean export's standard errors and relative, and whether EM
  converged.

Conventions come twice: undeclared (the sidecar as pinquad writes it) and declared
(the sidecar's key added); then declared falsely (a key added to the sidecar of a log not
written that way), and read with a vehicle file that is false in one key or of another
vehicle (``pinquad.io.declaration_check``). The table goes to stdout (and ``--out``) as
markdown.

    PYTHONPATH=$PWD python scripts/convention_variants.py [--log PATH] [--out table.md]
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from pinquad.io.declared import Conventions
from pinquad.io.foreign import write_foreign
from pinquad.io.logs import FlightLog, LogFormatError, write_log
from pinquad.pipeline.identify import LogOptions, plausible_range
from pinquad.pipeline.single import identify, read

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "crazyflie" / "imrc_brushed"
QUAT = ("quat_w", "quat_x", "quat_y", "quat_z")
OPTIONS = LogOptions(msteps=("regressor",), information=False)

CONVENTIONS = (
    ("quaternion stored x, y, z, w", Conventions(quaternion_order="xyzw"), ()),
    ("NED world and FRD body (PX4, ArduPilot)", Conventions(frame="NED/FRD"), ()),
    ("quaternion of the inverse rotation (world in body)",
     Conventions(quaternion_rotation="world_to_body"), ()),
    ("rotor speeds in rad/s instead of rev/min", Conventions(rotor_speed="rad/s"), ()),
    ("motor numbering rotated (2, 3, 4, 1)", Conventions(motor_order=(2, 3, 4, 1)), ()),
    ("Euler angles in degrees (roll, pitch, yaw columns)", Conventions(euler_unit="deg"), QUAT),
)
FALSE_DECLARATIONS = (  # (variant, as written, columns left out, the false sidecar keys)
    ("w, x, y, z quaternion declared x, y, z, w", Conventions(), (),
     {"quaternion": {"order": "xyzw"}}),
    ("body-to-world quaternion declared world to body", Conventions(), (),
     {"quaternion": {"rotation": "world_to_body"}}),
    ("ENU/FLU log declared NED/FRD", Conventions(), (), {"frame": "NED/FRD"}),
    ("... and the motor order the old refusal advised", Conventions(), (),
     {"frame": "NED/FRD", "motor_order": [2, 1, 4, 3]}),
    ("NED/FRD log declared ENU/FLU", Conventions(frame="NED/FRD"), (), {"frame": "ENU/FLU"}),
    ("motor numbering as the vehicle's, declared (2, 3, 4, 1)", Conventions(), (),
     {"motor_order": [2, 3, 4, 1]}),
    ("numbered (2, 3, 4, 1), declared (3, 4, 1, 2)", Conventions(motor_order=(2, 3, 4, 1)), (),
     {"motor_order": [3, 4, 1, 2]}),
    ("rev/min declared rad/s", Conventions(), (), {"rotor_speed": "rad/s"}),
    ("Euler angles in degrees declared rad", Conventions(euler_unit="deg"), QUAT,
     {"euler": {"unit": "rad"}}),
)
VEHICLE_FILES = (  # (variant, the file's text from crazyflie21.toml, or a shipped file)
    ("crazyflie21.toml given as a file", None, ROOT / "pinquad" / "data" / "crazyflie21.toml"),
    ("crazyflie21.toml with its yaw spins flipped", ("spin = [-1, 1, -1, 1]",
                                                     "spin = [1, -1, 1, -1]"), None),
    ("the brushless build's file (cf21_brushless.toml)", None,
     ROOT / "docs" / "vehicles" / "cf21_brushless.toml"),
    ("a 0.5 kg quadcopter's file (quad250_plus.toml)", None,
     ROOT / "docs" / "vehicles" / "quad250_plus.toml"),
)


def estimate(log: FlightLog, information: bool = False):
    """([m, I_xx, I_yy, I_zz], stderr (4,), converged, failure, result) of the regressor
    run."""
    result = identify(log, replace(OPTIONS, information=information))
    run = result.runs[0]
    return (np.r_[run.mass, np.diag(run.inertia)], np.asarray(run.stderr), run.converged,
            run.failure, result)


def outcome(log_path: Path, base: np.ndarray, se: np.ndarray, vehicle: Path | None = None
            ) -> str:
    """What the pipeline's read and identify steps do with the log at log_path (read
    with ``vehicle``, as ``--vehicle`` gives it), in words."""
    try:
        log = read(log_path, None if vehicle is None else str(vehicle))
        est, _, converged, failure, result = estimate(log)
    except (LogFormatError, ValueError) as exc:
        return f"exit 2: `{exc}`".replace(str(log_path.parent) + "/", "").replace(
            str(ROOT) + "/", "")
    change = np.abs(est - base)
    worst = int(np.argmax(change / se))
    names = ("mass", "I_xx", "I_yy", "I_zz")
    words = (f"max change {np.max(change / se):.2g} standard errors ({names[worst]}), "
             f"{np.max(change / np.abs(base)):.1e} relative; "
             f"{'converged' if converged else 'not converged'}")
    if failure:
        words += f"; failure: {failure}"
    gaps = [line for line in result.excluded if "log gap" in line]
    if gaps:
        words += f"; excluded: {gaps[0]}"
    return words


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--log", type=Path, default=DATA / "jana00")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    rows = ["| variant | sidecar | what pinquad does |", "|---|---|---|"]
    print("\n".join(rows), flush=True)

    def row(variant: str, side: str, words: str) -> None:
        rows.append(f"| {variant} | {side} | {words} |")
        print(rows[-1], flush=True)

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        t0 = time.perf_counter()
        clean = read(write_log(replace(read(args.log), measured=None),
                                   folder / "flight.parquet"))
        base, se, converged, _, _ = estimate(clean, information=True)
        row("clean export", "as written", f"mass {base[0] * 1e3:.3f} g, inertia "
            f"{', '.join(f'{v * 1e6:.2f}' for v in base[1:])} e-6 kg m^2 (standard errors "
            f"{se[0] * 1e3:.3f} g, {', '.join(f'{v * 1e6:.2f}' for v in se[1:])}); "
            f"{'converged' if converged else 'not converged'}")
        rng = np.random.default_rng(2)
        t = np.sort(clean.t + rng.uniform(-2e-3, 2e-3, clean.n))
        jitter = write_log(replace(clean, t=t - t[0]), folder / "jitter.parquet")
        row("time stamps with 2 ms jitter", "as written", outcome(jitter, base, se))
        unix = write_log(replace(clean, t=clean.t + 1.7e9), folder / "unix.parquet")
        row("time stamps in Unix time (t + 1.7e9 s)", "as written", outcome(unix, base, se))
        for name, conv, drop in CONVENTIONS:
            for declare in (False, True):
                path = write_foreign(clean, folder / f"{len(rows)}.parquet", conv, declare,
                                     drop)
                side = json.dumps(conv.sidecar()) if declare else "not declared"
                if drop:  # the clean reference for a log without quaternion columns
                    ref = write_foreign(clean, folder / f"ref{len(rows)}.parquet",
                                        Conventions(), False, drop)
                    b, s, *_ = estimate(read(ref), information=True)
                else:
                    b, s = base, se
                row(name, side, outcome(path, b, s))
        for name, written, drop, keys in FALSE_DECLARATIONS:
            path = write_foreign(clean, folder / f"{len(rows)}.parquet", written, False, drop)
            side = Path(str(path) + ".json")
            side.write_text(json.dumps({**json.loads(side.read_text()), **keys}))
            row(name, json.dumps(keys), outcome(path, base, se))
        for name, edit, shipped in VEHICLE_FILES:
            vehicle = shipped
            if edit is not None:
                vehicle = folder / "crazyflie21_edited.toml"
                text = (ROOT / "pinquad" / "data" / "crazyflie21.toml").read_text()
                vehicle.write_text(text.replace(*edit))
                shutil.copy(ROOT / "pinquad" / "data" / "crazyflie21.urdf", folder)
            row(name, f"--vehicle {vehicle.name}",
                outcome(folder / "flight.parquet", base, se, vehicle))
        bare = write_log(clean, folder / "bare.parquet")
        Path(str(bare) + ".json").unlink()
        est, _, _, _, result = estimate(read(bare))
        vrange = plausible_range(result.log)
        note = [n for n in result.notes if n.startswith("no vehicle named")]
        row("no sidecar", "none", f"judged against "
            f"{'no vehicle' if vrange is None else vrange.source}; note: "
            f"{note[0] if note else '(none)'}; max change "
            f"{np.max(np.abs(est - base) / se):.2g} standard errors")
        keep = (clean.t < 3.0) | (clean.t >= 5.0)
        holed = clean.slice(0, clean.n)
        holed = replace(holed, t=clean.t[keep], position=clean.position[keep],
                        velocity=clean.velocity[keep], euler=clean.euler[keep],
                        gyro=clean.gyro[keep], accel=clean.accel[keep], rpm=clean.rpm[keep],
                        vbat=None if clean.vbat is None else clean.vbat[keep])
        row("a 2 s gap (rows of 3-5 s removed)", "as written",
            outcome(write_log(holed, folder / "gap.parquet"), base, se))
        diag = write_log(replace(clean, meta=replace(
            clean.meta, inertia_guess=np.diag([1.6e-5, 1.7e-5, 2.9e-5]))), folder / "d.parquet")
        side = Path(str(diag) + ".json")
        raw = json.loads(side.read_text())
        raw["inertia_guess"] = [1.6e-5, 1.7e-5, 2.9e-5]
        side.write_text(json.dumps(raw))
        row("`inertia_guess` as a 3-vector", '"inertia_guess": [1.6e-5, 1.7e-5, 2.9e-5]',
            outcome(diag, base, se))
        rows.append(f"<!-- {time.perf_counter() - t0:.0f} s -->")
        print(rows[-1], flush=True)
    if args.out is not None:
        args.out.write_text("\n".join(rows) + "\n")


if __name__ == "__main__":
    main()
