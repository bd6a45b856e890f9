"""Unit errors in one column, dead or stuck rotor channels, a false rotor-speed
declaration and CSV dialects, written from real shared logs: what
``python -m pinquad.offline --log`` does with each (docs/bad_input.md).

jana00 of the shared IMRC brushed logs is exported as pinquad's Parquet log of rotor
speeds and, through crazyflie21's rotor model, as a thrust / torque CSV (100 Hz); the
Neural-Swarm flight randomwalk_l_cf102_01 is exported as a thrust / torque CSV naming
its vehicle file (docs/vehicles/cf21_parrot_frame.toml). Each variant runs through the
command's ``main`` (exit code and the first line it prints to stderr); nothing runs EM
except what the command itself runs (every variant below is refused before it, or, the
European CSV, read to the same columns as the plain file, compared here instead).

    PYTHONPATH=$PWD python scripts/unit_variants.py
"""

from __future__ import annotations

import contextlib
import io
import json
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from pinquad.cli.offline import main as offline
from pinquad.io.logs import FlightLog, read_table, write_log
from pinquad.io.read import read_log, with_vehicle
from pinquad.realdata.vehicle_check import measured_observations

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
JANA00 = SHARED / "crazyflie" / "imrc_brushed" / "jana00"
PARROT = SHARED / "neural_swarm" / "flights" / "randomwalk_l_cf102_01"


def run(path: Path, out: Path) -> str:
    """'exit N: first stderr line' of offline --log path (file paths shortened)."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = offline(["--log", str(path), "--out", str(out), "--no-discover"])
    first = next((ln for ln in err.getvalue().splitlines() if ln.strip()), "")
    if not out.exists():
        return f"exit {code}, nothing written: `{first.replace(str(path.parent) + '/', '')}`"
    report = json.loads((out / "report.json").read_text())
    est = report["estimates"]
    inertia = np.diag(np.asarray(est["inertia"])) * 1e6
    verdict = report.get("verdict", {})
    words = verdict.get("overall", verdict) if isinstance(verdict, dict) else verdict
    return (f"exit {code}: mass {est['mass'] * 1e3:.2f} g, I {', '.join(f'{v:.3g}' for v in inertia)}"
            f" e-6 kg m^2; verdict {words}")


def scaled(log: FlightLog, **columns) -> FlightLog:
    return replace(log, **columns)


def main() -> None:
    print("| log | variant | `offline --log` |")
    print("|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        sd = read_log(JANA00)
        rpm = read_table(write_log(replace(sd, measured=None, meta=replace(
            sd.meta, vehicle="crazyflie21", vehicle_named=True)), d / "jana00.parquet"))
        grid = measured_observations(rpm).log
        wrench = read_table(write_log(replace(grid, rpm=None, meta=replace(
            grid.meta, wrench_from_rpm=False, vehicle="crazyflie21", vehicle_named=True,
            actuation="sampled")), d / "jana00.csv"))
        ns = with_vehicle(read_log(PARROT), str(ROOT / "docs" / "vehicles" /
                                                  "cf21_parrot_frame.toml"), ROOT, "--vehicle")
        ns = read_table(write_log(ns, d / "cf102_01.csv"))
        third = 2 * rpm.n // 3

        def row(name: str, variant: str, log: FlightLog, suffix: str = ".csv",
                sidecar: dict | None = None) -> None:
            path = write_log(log, d / f"v{row.k}{suffix}")
            row.k += 1
            if sidecar:
                side = Path(f"{path}.json")
                side.write_text(json.dumps({**json.loads(side.read_text()), **sidecar}))
            print(f"| {name} | {variant} | {run(path, d / f'run{row.k}')} |", flush=True)
        row.k = 0  # type: ignore[attr-defined]

        row("jana00 (thrust, torques)", "clean", wrench)
        row("randomwalk_l_cf102_01 (Neural-Swarm, Parrot frame)", "clean", ns)
        r = rpm.rpm.copy()
        r[third:, 2] = 0.0
        row("jana00 (rotor speeds)", "rpm_3 reads 0 for the last third", scaled(rpm, rpm=r),
            ".parquet")
        r = rpm.rpm.copy()
        r[third:, 2] = np.median(r[:, 2])
        row("jana00 (rotor speeds)", "rpm_3 stuck at its median (hover) for the last third",
            scaled(rpm, rpm=r), ".parquet")
        row("jana00 (rotor speeds)", 'rev/min declared "rotor_speed": "rad/s"', rpm,
            ".parquet", {"rotor_speed": "rad/s"})
        for name, log in (("jana00 (thrust, torques)", wrench),
                          ("randomwalk_l_cf102_01 (Neural-Swarm, Parrot frame)", ns)):
            row(name, "thrust normalised 0..1 (divided by 0.6 N)" if log is wrench else
                "thrust normalised 0..1 (divided by 1.2 N)",
                scaled(log, thrust=log.thrust / (0.6 if log is wrench else 1.2)))
            row(name, "torques x10", scaled(log, torque=log.torque * 10))
            row(name, "torques in N mm", scaled(log, torque=log.torque * 1000))
            for k, axis in ((0, "x"), (2, "z")):
                g = log.gyro.copy()
                g[:, k] *= 180 / np.pi
                row(name, f"gyro_{axis} alone in deg/s", scaled(log, gyro=g))
            a = log.accel.copy()
            a[:, 0] /= 9.81
            row(name, "acc_x alone in g", scaled(log, accel=a))
        src = Path(d / "jana00.csv").read_text().splitlines()
        k = src[0].split(",").index("gyro_x")
        dup = d / "dup.csv"
        dup.write_text("\n".join([src[0] + ",gyro_x"] + [
            ln + "," + (repr(float(ln.split(",")[k]) * 180 / np.pi) if ln.split(",")[k] else "")
            for ln in src[1:]]) + "\n")
        Path(f"{dup}.json").write_text(Path(d / "jana00.csv.json").read_text())
        print(f"| jana00 (thrust, torques) | a second `gyro_x` column (deg/s) after the "
              f"others | {run(dup, d / 'run_dup')} |")
        eu = d / "eu.csv"
        eu.write_text("\n".join([src[0].replace(",", ";")] + [
            ln.replace(",", ";").replace(".", ",") for ln in src[1:]]) + "\n")
        Path(f"{eu}.json").write_text(Path(d / "jana00.csv.json").read_text())
        a, b = read_table(eu), read_table(d / "jana00.csv")
        same = all(np.array_equal(x, y, equal_nan=True) for x, y in (
            (a.t, b.t), (a.position, b.position), (a.euler, b.euler), (a.gyro, b.gyro),
            (a.accel, b.accel), (a.thrust, b.thrust), (a.torque, b.torque)))
        note = next(n for n in a.meta.notes if "decimal mark" in n)
        print(f"| jana00 (thrust, torques) | European CSV (`;` between fields, decimal "
              f"commas) | read: every column equal to the plain CSV's: {same}; note: "
              f"{note} |")


if __name__ == "__main__":
    main()
