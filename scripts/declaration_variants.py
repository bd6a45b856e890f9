"""Shared flights declared wrongly, as users declare them: what ``offline --log`` does with
each, against the right answer.

From the shared logs (the IMRC micro-SD jana00 and eckart00, jana00's CSV export, the
first 30 s of a Neural-Swarm Parrot-frame flight exported as CSV, the PX4
data-driven-dynamics sample) this builds, in a temporary directory:

* every shipped vehicle file (``pinquad/data/crazyflie21.toml``, ``docs/vehicles/*.toml``)
  on each other vehicle's log (``--vehicle``; on the PX4 sample ``--mass file``, the
  file's reference mass);
* the vehicle file with its yaw spin signs flipped;
* each sidecar convention declared falsely on columns written in pinquad's own
  (quaternion order ``xyzw`` and rotation ``world_to_body``, frame ``NED/FRD`` alone and
  with ``motor_order [2, 1, 4, 3]``, a false ``motor_order``, ``rotor_speed`` ``rad/s``,
  Euler angles in ``deg`` and in another order);
* units: the commanded thrust normalised 0..1 (divided by a 1.3 N full scale), torques
  in N mm (x1000) and x10, one gyro axis in deg/s, the accelerometer in g;
* a motor channel at zero for the last third, one stuck at its median (hover) for the
  middle third;
* a European CSV (``;`` between fields, decimal commas); a second ``gyro_x`` column.

Each runs ``python -m pinquad.offline --log LOG [--vehicle FILE] --no-discover --mstep
regressor --jobs 1 --out DIR`` (the regressor M-step is the headline's; the paper's
closed form adds nothing to the verdict; the PX4 sample runs in known-mass mode,
``--mass``, whose headline is its regression and whose mass is the user's, "given") and
the markdown table printed has, per variant: exit code; the first message line (the
error paragraph's first 120 characters, else the ``verdict:`` line, or the known-mass
mode's first line); the estimate with its total standard errors; the headline's verdicts
of mass, I_xx, I_yy, I_zz; and the parameters
that are trusted yet more than 2 total standard errors from the right answer (the clean
log's estimate with its total standard error: the same log, truthfully declared). The
last line counts the variants with such a parameter (violations).

    PYTHONPATH=$PWD python scripts/declaration_variants.py [--jobs N] [--out table.md]
        [--only WORD ...] [--keep DIR]

--jobs N runs N variants at a time (each with one worker); --only keeps the variants
whose name holds a word, and the clean runs they are compared with; --keep leaves the
built logs and run directories in DIR. The 37 runs (31 variants, 6 clean) take 640 s
with --jobs 2 on the 2-core machine shared with other jobs (the three PX4 runs 140-200 s
each, a full run 30-55 s, a refusal 7-23 s); with most variants identified rather than
refused, 1841 s under a heavier load.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from pinquad.io.logs import write_log
from pinquad.io.read import read_log

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data"
JANA00 = DATA / "crazyflie" / "imrc_brushed" / "jana00"
ECKART00 = DATA / "crazyflie" / "imrc_brushless" / "eckart00"
PARROT_FLIGHT = DATA / "neural_swarm" / "flights" / "randomwalk_l_cf102_01"
DDD_CSV = DATA / "px4" / "ddd_quadrotor_model.csv"
DDD_YAML = DATA / "px4" / "ddd_quadrotor_model.yaml"
VEHICLES = {"crazyflie21": REPO / "pinquad" / "data" / "crazyflie21.toml",
            "cf21_brushless": REPO / "docs" / "vehicles" / "cf21_brushless.toml",
            "cf21_parrot_frame": REPO / "docs" / "vehicles" / "cf21_parrot_frame.toml",
            "quad250_plus": REPO / "docs" / "vehicles" / "quad250_plus.toml"}
PARROT_SECONDS = 30.0
"""The Neural-Swarm flight's export keeps its first 30 s (of 64): the run time."""
THRUST_FULL_SCALE = 1.3
"""The commanded thrust [N] that a normalised 0..1 log writes as 1 (hover ~0.5)."""
NAMES = ("mass", "I_xx", "I_yy", "I_zz")
SHORT = {"trusted": "T", "not identifiable": "NI", "model not adequate": "NA",
         "implausible": "IMP", "not judged": "NJ", "given": "given"}
TIMEOUT_S = 1800


@dataclass(frozen=True)
class Variant:
    """One case: name; base: the clean log it is built from (a key of the built logs);
    build: (the base's path, the output folder) -> the log to run; args: more command
    line; ref: the name of the clean variant whose estimate is the right answer (None:
    this is a clean reference)."""

    name: str
    base: str
    build: Callable[[Path, Path], Path] | None = None
    args: tuple[str, ...] = ()
    ref: str | None = None
    known_mass: bool = False


@dataclass
class Outcome:
    """What one run gave: exit code, first message line, values (4,) [kg, kg m^2],
    total standard errors (4,), verdicts by name, seconds."""

    code: int
    message: str
    values: np.ndarray = field(default_factory=lambda: np.full(4, np.nan))
    stderr: np.ndarray = field(default_factory=lambda: np.full(4, np.nan))
    verdicts: dict[str, str] = field(default_factory=dict)
    seconds: float = 0.0


# ------------------------------------------------------------------ building the logs

def _csv(path: Path) -> tuple[list[str], np.ndarray]:
    lines = path.read_text().splitlines()
    return lines[0].split(","), np.array([[float(v) if v else np.nan for v in ln.split(",")]
                                          for ln in lines[1:]])


def _field(value: float) -> str:
    """A CSV field as pinquad writes it: empty for a missing value."""
    return repr(float(value)) if np.isfinite(value) else ""


def _write_csv(path: Path, header: list[str], table: np.ndarray, sidecar: dict) -> Path:
    path.write_text(",".join(header) + "\n" + "\n".join(
        ",".join(_field(v) for v in row) for row in table) + "\n")
    Path(f"{path}.json").write_text(json.dumps(sidecar, indent=2))
    return path


def _sidecar(path: Path) -> dict:
    return json.loads(Path(f"{path}.json").read_text())


def edited(name: str, change: Callable[[list[str], np.ndarray, dict], None]
           ) -> Callable[[Path, Path], Path]:
    """A builder: the base CSV with ``change(header, table, sidecar)`` applied in place."""
    def build(base: Path, folder: Path) -> Path:
        header, table = _csv(base)
        side = _sidecar(base)
        change(header, table, side)
        return _write_csv(folder / f"{name}.csv", header, table, side)
    return build


def declared(name: str, **keys: object) -> Callable[[Path, Path], Path]:
    """A builder: the base CSV as it is, its sidecar with ``keys`` added (a false
    declaration: the columns are pinquad's own)."""
    def change(header: list[str], table: np.ndarray, side: dict) -> None:
        side.update(keys)
    return edited(name, change)


def column(header: list[str], name: str) -> int:
    return header.index(name)


def scale_columns(names: tuple[str, ...], factor: float) -> Callable:
    def change(header: list[str], table: np.ndarray, side: dict) -> None:
        for n in names:
            table[:, column(header, n)] *= factor
    return change


def motor_zero_last_third(header: list[str], table: np.ndarray, side: dict) -> None:
    n = table.shape[0]
    table[2 * n // 3:, column(header, "rpm_1")] = 0.0


def motor_stuck_middle_third(header: list[str], table: np.ndarray, side: dict) -> None:
    n = table.shape[0]
    j = column(header, "rpm_2")
    table[n // 3:2 * n // 3, j] = float(np.median(table[:, j]))


def thrust_normalised(header: list[str], table: np.ndarray, side: dict) -> None:
    table[:, column(header, "thrust")] /= THRUST_FULL_SCALE


def european(base: Path, folder: Path) -> Path:
    """The CSV with ';' between fields and decimal commas, as a European spreadsheet
    writes it."""
    header, table = _csv(base)
    path = folder / "european.csv"
    path.write_text(";".join(header) + "\n" + "\n".join(
        ";".join(_field(v).replace(".", ",") for v in row) for row in table) + "\n")
    shutil.copy(f"{base}.json", f"{path}.json")
    return path


def duplicated_gyro_x(base: Path, folder: Path) -> Path:
    """A second ``gyro_x`` column after the others, holding the x rate in deg/s (a
    logger's raw and converted channels under one name)."""
    header, table = _csv(base)
    extra = np.degrees(table[:, column(header, "gyro_x")])[:, None]
    return _write_csv(folder / "duplicated.csv", [*header, "gyro_x"], np.hstack([table, extra]),
                      _sidecar(base))


def euler_only(base: Path, folder: Path) -> Path:
    """The CSV without its quaternion columns (attitude from roll, pitch, yaw)."""
    header, table = _csv(base)
    keep = [i for i, h in enumerate(header) if not h.startswith("quat_")]
    return _write_csv(folder / "euler_only.csv", [header[i] for i in keep], table[:, keep],
                      _sidecar(base))


def euler_only_declared(name: str, **keys: object) -> Callable[[Path, Path], Path]:
    def build(base: Path, folder: Path) -> Path:
        header, table = _csv(base)
        keep = [i for i, h in enumerate(header) if not h.startswith("quat_")]
        side = {**_sidecar(base), **keys}
        return _write_csv(folder / f"{name}.csv", [header[i] for i in keep], table[:, keep], side)
    return build


def flipped_spin(vehicle: str) -> Callable[[Path, Path], Path]:
    """A builder of the vehicle file with its yaw spin signs negated (returns the file;
    the log is the base's)."""
    def build(base: Path, folder: Path) -> Path:
        text = VEHICLES[vehicle].read_text()
        match = re.search(r"^spin = \[([^\]]*)\]", text, flags=re.M)
        assert match, f"{VEHICLES[vehicle]}: no spin line"
        signs = [-int(s) for s in match.group(1).split(",")]
        out = folder / f"{vehicle}_flipped_spin.toml"
        out.write_text(text[:match.start()] + f"spin = {signs}" + text[match.end():])
        return out
    return build


def base_logs(folder: Path) -> dict[str, Path]:
    """The clean logs every variant starts from."""
    logs = {"jana00": JANA00, "eckart00": ECKART00, "ddd": DDD_CSV}
    jana = read_log(JANA00)
    logs["jana00.csv"] = write_log(replace(jana, measured=None), folder / "jana00.csv")
    parrot = read_log(PARROT_FLIGHT)
    rows = int(np.searchsorted(parrot.t, PARROT_SECONDS))
    path = write_log(replace(parrot.slice(0, rows), measured=None), folder / "parrot.csv")
    side = _sidecar(path)
    side.pop("vehicle", None)  # the flight names no vehicle; the run declares it (--vehicle)
    Path(f"{path}.json").write_text(json.dumps(side, indent=2))
    logs["parrot.csv"] = path
    return logs


# ------------------------------------------------------------------------ the variants

PARROT = ("--vehicle", str(VEHICLES["cf21_parrot_frame"]))
BRUSHLESS = ("--vehicle", str(VEHICLES["cf21_brushless"]))


def variants() -> list[Variant]:
    out = [
        Variant("clean: jana00 micro-SD (crazyflie21 by its format)", "jana00"),
        Variant("clean: jana00 CSV export", "jana00.csv"),
        Variant("clean: jana00 CSV export, Euler columns only", "jana00.csv", euler_only),
        Variant("clean: eckart00 micro-SD, --vehicle cf21_brushless", "eckart00", args=BRUSHLESS),
        Variant("clean: Neural-Swarm cf102_01 CSV (30 s), --vehicle cf21_parrot_frame",
                "parrot.csv", args=PARROT),
        Variant("clean: PX4 sample, --mass 1.5 --vehicle its yaml", "ddd",
                args=("--mass", "1.5", "--vehicle", str(DDD_YAML)), known_mass=True),
    ]
    refs = {"jana00": out[0].name, "jana00.csv": out[1].name, "euler": out[2].name,
            "eckart00": out[3].name, "parrot.csv": out[4].name, "ddd": out[5].name}
    own = {"jana00": "crazyflie21", "eckart00": "cf21_brushless", "parrot.csv": "cf21_parrot_frame"}
    for base, mine in own.items():
        for other, path in VEHICLES.items():
            if other != mine:
                out.append(Variant(f"vehicle file {other} on {base}", base,
                                   args=("--vehicle", str(path)), ref=refs[base]))
    for other in ("crazyflie21", "quad250_plus"):
        out.append(Variant(f"vehicle file {other} on the PX4 sample (--mass file)", "ddd",
                           args=("--mass", "file", "--vehicle", str(VEHICLES[other])),
                           ref=refs["ddd"], known_mass=True))
    out += [
        Variant("yaw spin signs flipped: crazyflie21 on jana00", "jana00",
                flipped_spin("crazyflie21"), ref=refs["jana00"]),
        Variant("yaw spin signs flipped: cf21_brushless on eckart00", "eckart00",
                flipped_spin("cf21_brushless"), ref=refs["eckart00"]),
        Variant('false "quaternion": {"order": "xyzw"} (columns named by component)',
                "jana00.csv", declared("q_xyzw", quaternion={"order": "xyzw"}),
                ref=refs["jana00.csv"]),
        Variant('false "quaternion": {"rotation": "world_to_body"}', "jana00.csv",
                declared("q_inv", quaternion={"rotation": "world_to_body"}),
                ref=refs["jana00.csv"]),
        Variant('false "frame": "NED/FRD" on an ENU/FLU log', "jana00.csv",
                declared("ned", frame="NED/FRD"), ref=refs["jana00.csv"]),
        Variant('false "frame": "NED/FRD" with "motor_order": [2, 1, 4, 3]', "jana00.csv",
                declared("ned_order", frame="NED/FRD", motor_order=[2, 1, 4, 3]),
                ref=refs["jana00.csv"]),
        Variant('false "motor_order": [2, 3, 4, 1]', "jana00.csv",
                declared("order", motor_order=[2, 3, 4, 1]), ref=refs["jana00.csv"]),
        Variant('false "rotor_speed": "rad/s"', "jana00.csv",
                declared("rads", rotor_speed="rad/s"), ref=refs["jana00.csv"]),
        Variant('false "euler": {"unit": "deg"} (Euler columns in rad)', "jana00.csv",
                euler_only_declared("deg", euler={"unit": "deg"}), ref=refs["euler"]),
        Variant('false "euler": {"order": "XYZ"}', "jana00.csv",
                euler_only_declared("xyz", euler={"order": "XYZ"}), ref=refs["euler"]),
        Variant('false "frame": "NED/FRD" on the Neural-Swarm CSV', "parrot.csv",
                declared("ns_ned", frame="NED/FRD"), args=PARROT, ref=refs["parrot.csv"]),
        Variant(f"thrust normalised 0..1 (/ {THRUST_FULL_SCALE} N)", "parrot.csv",
                edited("thrust01", thrust_normalised), args=PARROT, ref=refs["parrot.csv"]),
        Variant("torques in N mm (x1000)", "parrot.csv",
                edited("nmm", scale_columns(("torque_x", "torque_y", "torque_z"), 1000.0)),
                args=PARROT, ref=refs["parrot.csv"]),
        Variant("torques x10", "parrot.csv",
                edited("x10", scale_columns(("torque_x", "torque_y", "torque_z"), 10.0)),
                args=PARROT, ref=refs["parrot.csv"]),
        Variant("gyro_x in deg/s (the other axes rad/s)", "jana00.csv",
                edited("gyro_deg", scale_columns(("gyro_x",), 180.0 / np.pi)),
                ref=refs["jana00.csv"]),
        Variant("accelerometer in g", "jana00.csv",
                edited("acc_g", scale_columns(("acc_x", "acc_y", "acc_z"), 1.0 / 9.81)),
                ref=refs["jana00.csv"]),
        Variant("rpm_1 at 0 for the last third", "jana00.csv",
                edited("zero", motor_zero_last_third), ref=refs["jana00.csv"]),
        Variant("rpm_2 stuck at its median for the middle third", "jana00.csv",
                edited("stuck", motor_stuck_middle_third), ref=refs["jana00.csv"]),
        Variant("European CSV (';', decimal commas)", "jana00.csv", european,
                ref=refs["jana00.csv"]),
        Variant("duplicated gyro_x header (the second in deg/s)", "jana00.csv",
                duplicated_gyro_x, ref=refs["jana00.csv"]),
    ]
    return out


# ------------------------------------------------------------------------- running

def first_message(code: int, stdout: str, stderr: str) -> str:
    """The error paragraph's first 120 characters, else the verdict line."""
    if code not in (0, 3):
        text = " ".join(stderr.split())
        text = text[text.find("error:"):] if "error:" in text else text
        return text[:120] + ("..." if len(text) > 120 else "")
    for line in stdout.splitlines():
        if line.startswith(("verdict:", "known mass")):
            return line.strip()[:120]
    return next((ln.strip() for ln in stdout.splitlines() if "verdict" in ln), "")[:120]


def read_report(report: dict, known_mass: bool) -> tuple[np.ndarray, np.ndarray, dict]:
    """(values (4,), total standard errors (4,), verdicts) of a report.json's headline."""
    if known_mass:
        return known_mass_estimates(report)
    est = report["estimates"]
    values = np.r_[est["mass"], np.diag(np.asarray(est["inertia"], dtype=float))]
    se = np.r_[est["stderr"]["mass"], est["stderr"]["inertia_diag"]]
    verdicts = {k: v["verdict"] for k, v in est["verdict"]["parameters"].items()}
    return values.astype(float), np.array([np.nan if s is None else s for s in se]), verdicts


def known_mass_estimates(report: dict) -> tuple[np.ndarray, np.ndarray, dict]:
    """The known-mass mode's headline (its regression): the mass the user gave (verdict
    "given"), I_xx, I_yy, I_zz with their total standard errors and verdicts."""
    est = report["estimates"]

    def num(x: object) -> float:
        return np.nan if x is None else float(x)  # type: ignore[arg-type]

    values = np.array([num(est["mass"])] + [num(est["inertia"][i][i]) for i in range(3)])
    se = np.array([num(est["stderr"]["mass"])] + [num(x) for x in est["stderr"]["inertia_diag"]])
    verdicts = {"mass": "given"}
    verdicts.update({n: est["verdict"][n]["verdict"] for n in NAMES[1:] if n in est["verdict"]})
    return values, se, verdicts


def run_one(variant: Variant, log: Path, vehicle: Path | None, out: Path) -> Outcome:
    cmd = [sys.executable, "-m", "pinquad.offline", "--log", str(log), "--no-discover",
           "--jobs", "1", "--out", str(out)]
    if not variant.known_mass:  # the known-mass mode runs its regression and EM always
        cmd += ["--mstep", "regressor"]
    cmd += list(variant.args)
    if vehicle is not None:
        cmd += ["--vehicle", str(vehicle)]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO,
                              timeout=TIMEOUT_S, env={**os.environ, "PYTHONPATH": str(REPO)})
        code, stdout, stderr = proc.returncode, proc.stdout, proc.stderr
    except subprocess.TimeoutExpired:
        code, stdout, stderr = -1, "", f"error: timed out after {TIMEOUT_S} s"
    outcome = Outcome(code, first_message(code, stdout, stderr),
                      seconds=time.perf_counter() - t0)
    if "Traceback" in stderr:
        outcome.message = "TRACEBACK: " + " ".join(stderr.split())[-110:]
    print(f"{variant.name}: exit {code} ({outcome.seconds:.0f} s)", file=sys.stderr, flush=True)
    (out.parent / "stdout.txt").write_text(stdout)
    (out.parent / "stderr.txt").write_text(stderr)
    report = out / "report.json"
    if code in (0, 3) and report.is_file():
        outcome.values, outcome.stderr, outcome.verdicts = read_report(
            json.loads(report.read_text()), variant.known_mass)
    return outcome


def beyond(outcome: Outcome, right: Outcome | None) -> list[str]:
    """The parameters trusted more than 2 of the right answer's total standard errors
    from its value, as 'name z' (z in those standard errors)."""
    if right is None:
        return []
    out = []
    for i, name in enumerate(NAMES):
        if outcome.verdicts.get(name) != "trusted":
            continue
        se = right.stderr[i]
        if not (np.isfinite(outcome.values[i]) and np.isfinite(right.values[i]) and se > 0):
            continue
        z = abs(outcome.values[i] - right.values[i]) / se
        if z > 2.0:
            out.append(f"{name} {z:.1f}")
    return out


def verdict_cell(outcome: Outcome) -> str:
    if not outcome.verdicts:
        return "-"
    return "/".join(SHORT.get(outcome.verdicts.get(n, "-"), outcome.verdicts.get(n, "-"))
                    for n in NAMES)


def values_cell(outcome: Outcome) -> str:
    if not np.isfinite(outcome.values).any():
        return "-"
    v, s = outcome.values, outcome.stderr
    scale = 1.0 if v[1] > 1e-3 else 1e6  # kg m^2 for a 1.5 kg vehicle, else e-6
    return (f"{1e3 * v[0]:.4g} ± {1e3 * s[0]:.2g} g; " + ", ".join(
        f"{scale * v[i]:.4g} ± {scale * s[i]:.2g}" for i in range(1, 4))
        + (" e-6 kg m^2" if scale > 1 else " kg m^2"))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--only", nargs="*", default=None)
    ap.add_argument("--keep", type=Path, default=None)
    args = ap.parse_args()
    chosen = variants()
    if args.only:
        picked = [v for v in chosen if any(w in v.name for w in args.only)]
        refs = {v.ref for v in picked}
        chosen = [v for v in chosen if v in picked or v.name in refs]
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="pinquad_declared_") as tmp:
        folder = Path(tmp) if args.keep is None else args.keep
        folder.mkdir(parents=True, exist_ok=True)
        logs = base_logs(folder)
        jobs = []
        for k, v in enumerate(chosen):
            case = folder / f"case{k:02d}"
            case.mkdir(exist_ok=True)
            log, vehicle = logs[v.base], None
            if v.build is not None:
                built = v.build(logs[v.base], case)
                if built.suffix == ".toml":
                    vehicle = built
                else:
                    log = built
            jobs.append((v, log, vehicle, case / "run"))
        with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
            outcomes = list(pool.map(lambda j: run_one(*j), jobs))
    by_name = {v.name: o for v, o in zip(chosen, outcomes, strict=True)}
    rows = ["| variant | exit | first message line | estimate (total se) | verdicts m/xx/yy/zz "
            "| trusted beyond 2 total se of the right answer | s |", "|---" * 7 + "|"]
    violations = 0
    for v, o in zip(chosen, outcomes, strict=True):
        bad = beyond(o, by_name.get(v.ref) if v.ref else None)
        violations += bool(bad)
        cell = "(right answer)" if v.ref is None else (", ".join(bad) if bad else "none")
        message = o.message.replace("|", "\\|").replace(str(folder) + "/", "")
        rows.append(f"| {v.name} | {o.code} | {message} | {values_cell(o)} | {verdict_cell(o)} "
                    f"| {cell} | {o.seconds:.0f} |")
    wrong = sum(v.ref is not None for v in chosen)
    rows.append("")
    rows.append("verdicts: T trusted, NI not identifiable, NA model not adequate, IMP "
                "implausible, NJ not judged; given: the user's mass (--mass)")
    rows.append(f"violations: {violations} of {wrong} variants have a parameter trusted beyond "
                f"2 total standard errors of the right answer; "
                f"{sum(o.code == 2 for v, o in zip(chosen, outcomes, strict=True) if v.ref)} "
                f"refused (exit 2); {time.perf_counter() - t0:.0f} s with --jobs {args.jobs}")
    text = "\n".join(rows)
    print(text)
    if args.out is not None:
        args.out.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
