"""kf from any vehicle's steady thrust measurements: a CSV of rotor speed and measured
thrust, units in the header (``weight[g]``, ``thrust[N]``, ``rpm``, ``omega[rad/s]``) or
given, one row per steady point.

Model (per rotor T_i = kf omega_i^2, all rotors on the stand at once):

    T_total [N] = kf * S,   S = sum_i omega_i^2 [(rad/s)^2]

with S = motors * omega^2 when one speed column stands for every rotor. kf is the
least-squares fit through the origin, kf = sum S T / sum S^2; its standard error is
the textbook one from the residuals, se = sqrt(sum r^2 / (n - 1) / sum S^2), so a curve
that is not quadratic (propeller efficiency falling with speed) shows in the residual
and widens se.

Speeds may come from a second file logged during the same run (``speeds_from``): the
thrust file's key column (e.g. the commanded PWM of each step) is matched with the
log's, and each step's speed is the median over the second half of that step's rows
(the rotor has settled).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pinquad.io.logs import LogFormatError

Array = NDArray[np.float64]

THRUST_UNITS = {"n": 1.0, "g": 9.81e-3, "gf": 9.81e-3, "kg": 9.81, "mn": 1e-3}
"""[N] per unit of a thrust column (grams are grams-force, g = 9.81 m/s^2)."""
SPEED_UNITS = {"rpm": 2.0 * math.pi / 60.0, "rad/s": 1.0, "krpm": 2.0 * math.pi / 60.0 * 1e3}
"""[rad/s] per unit of a speed column."""


@dataclass(frozen=True)
class SteadyThrustFit:
    """kf fitted to steady points (module docstring).

    source: where the points came from; kf [N/(rad/s)^2], kf_se [N/(rad/s)^2];
    residual_rms [N]; n_points; motors: rotors the measured thrust is the total of;
    speed_rpm (n, k) [rev/min] and thrust (n,) [N]: the points used; notes.
    """

    source: str
    kf: float
    kf_se: float
    residual_rms: float
    n_points: int
    motors: int
    speed_rpm: Array
    thrust: Array
    notes: tuple[str, ...] = ()

    def residuals(self) -> Array:
        """(n,) measured minus fitted total thrust [N]."""
        return self.thrust - self.kf * _speed_sum(self.speed_rpm, self.motors)


def column_unit(name: str) -> tuple[str, str | None]:
    """("weight", "g") from ``weight[g]``; (name, None) without brackets."""
    name = name.strip()
    if name.endswith("]") and "[" in name:
        base, unit = name[:-1].split("[", 1)
        return base.strip(), unit.strip()
    return name, None


def read_csv_columns(path: str | Path) -> dict[str, Array]:
    """Columns of a headed numeric CSV by their header names (unparseable cells NaN).
    Raises LogFormatError if the file cannot be read or has no data rows."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError as exc:
        raise LogFormatError(f"{path}: cannot read ({exc.strerror})") from None
    if len(lines) < 2:
        raise LogFormatError(f"{path}: expected a header row and data rows")
    header = [h.strip() for h in lines[0].split(",")]
    rows = []
    for line in lines[1:]:
        if not line.strip():
            continue
        cells = line.split(",")
        row = []
        for i in range(len(header)):
            try:
                row.append(float(cells[i]))
            except (IndexError, ValueError):
                row.append(math.nan)
        rows.append(row)
    data = np.asarray(rows, dtype=float)
    return {h: data[:, i] for i, h in enumerate(header)}


def _speed_sum(speed_rpm: Array, motors: int) -> Array:
    omega = np.atleast_2d(speed_rpm.T).T * SPEED_UNITS["rpm"]
    s = (omega * omega).sum(axis=1)
    return s * motors if omega.shape[1] == 1 else s


def _find(cols: dict[str, Array], wanted: str | None, kinds: tuple[str, ...], path: Path,
          what: str) -> str:
    if wanted is not None:
        if wanted not in cols:
            raise LogFormatError(f"{path}: no column {wanted!r}; columns are {', '.join(cols)}")
        return wanted
    for name in cols:
        if column_unit(name)[0].lower() in kinds:
            return name
    raise LogFormatError(f"{path}: no {what} column (one named {', '.join(kinds)}); columns "
                         f"are {', '.join(cols)} (name it with an option)")


def _unit(name: str, given: str | None, table: dict[str, float], default: str, path: Path) -> float:
    unit = given or column_unit(name)[1] or default
    if unit.lower() not in table:
        raise LogFormatError(f"{path}: column {name!r}: unit {unit!r} not known; expected one "
                             f"of {', '.join(table)}")
    return table[unit.lower()]


def step_speeds(path: Path, key: str, speed_columns: tuple[str, ...]) -> dict[float, Array]:
    """{key value: (k,) median rotor speed [rev/min] over the second half of each run of
    rows holding that key value} from a log of the stand run."""
    cols = read_csv_columns(path)
    for c in (key, *speed_columns):
        if c not in cols:
            raise LogFormatError(f"{path}: no column {c!r}; columns are {', '.join(cols)}")
    k = cols[key]
    speeds = np.column_stack([cols[c] for c in speed_columns])
    out: dict[float, list[Array]] = {}
    start = 0
    for i in range(1, k.size + 1):
        if i == k.size or k[i] != k[start]:
            block = speeds[start + (i - start) // 2:i]
            if np.isfinite(k[start]) and block.size:
                out.setdefault(float(k[start]), []).append(block)
            start = i
    return {v: np.nanmedian(np.vstack(b), axis=0) for v, b in out.items()}


def fit_steady_thrust(path: str | Path, motors: int = 4, speed_columns: tuple[str, ...] = (),
                      thrust_column: str | None = None, speed_unit: str | None = None,
                      thrust_unit: str | None = None, speeds_from: str | Path | None = None,
                      join: tuple[str, str] | None = None,
                      speed_range: tuple[float, float] = (0.0, math.inf)) -> SteadyThrustFit:
    """Fit kf to a CSV of steady points (module docstring). ``join`` = (column in
    ``path``, column in ``speeds_from``) pairs each thrust row with a step of the
    speed log; speed_range [rev/min]: keep points whose mean speed lies inside.
    Raises LogFormatError (file, column) or ValueError (too few points)."""
    path = Path(path)
    cols = read_csv_columns(path)
    tcol = _find(cols, thrust_column, ("weight", "thrust", "force"), path, "thrust")
    thrust = cols[tcol] * _unit(tcol, thrust_unit, THRUST_UNITS, "N", path)
    notes = [f"thrust: column {tcol!r}"]
    if speeds_from is not None:
        if join is None or not speed_columns:
            raise ValueError("speeds from a second file need the join columns and the speed "
                             "column(s) to take from it")
        log = Path(speeds_from)
        steps = step_speeds(log, join[1], speed_columns)
        keys = cols.get(join[0])
        if keys is None:
            raise LogFormatError(f"{path}: no column {join[0]!r}; columns are {', '.join(cols)}")
        missing = [k for k in keys if float(k) not in steps]
        if missing:
            raise LogFormatError(f"{path}: {join[0]} value(s) {missing} have no rows in {log} "
                                 f"(column {join[1]!r})")
        scale = _unit(speed_columns[0], speed_unit, SPEED_UNITS, "rpm", log) / SPEED_UNITS["rpm"]
        speed = np.vstack([steps[float(k)] for k in keys]) * scale
        notes.append(f"speeds: median of {', '.join(speed_columns)} over the second half of "
                     f"each {join[1]} step in {log.name}, matched on {path.name}'s {join[0]}")
        source = f"{path.name} + {log.name}"
    else:
        names = speed_columns or (_find(cols, None, ("rpm", "omega", "speed"), path, "speed"),)
        for c in names:
            if c not in cols:
                raise LogFormatError(f"{path}: no column {c!r}; columns are {', '.join(cols)}")
        scale = _unit(names[0], speed_unit, SPEED_UNITS, "rpm", path) / SPEED_UNITS["rpm"]
        speed = np.column_stack([cols[c] for c in names]) * scale
        notes.append(f"speeds: column(s) {', '.join(names)}")
        source = path.name
    ok = np.isfinite(thrust) & np.isfinite(speed).all(axis=1)
    mean_speed = np.nanmean(speed, axis=1)
    inside = ok & (mean_speed >= speed_range[0]) & (mean_speed <= speed_range[1])
    if (ok & ~inside).any():
        notes.append(f"{int((ok & ~inside).sum())} point(s) outside {speed_range[0]:.0f}.."
                     f"{speed_range[1]:.0f} rev/min left out")
    if inside.sum() < 3:
        raise ValueError(f"{path}: {int(inside.sum())} usable point(s); expected at least 3")
    speed, thrust = speed[inside], thrust[inside]
    x = _speed_sum(speed, motors)
    kf = float(x @ thrust / (x @ x))
    r = thrust - kf * x
    se = float(math.sqrt((r @ r) / (r.size - 1) / (x @ x)))
    return SteadyThrustFit(source=source, kf=kf, kf_se=se,
                           residual_rms=float(np.sqrt(np.mean(r * r))), n_points=int(r.size),
                           motors=motors, speed_rpm=speed, thrust=thrust, notes=tuple(notes))


def actuator_section(kf: float, kf_se: float, comment: str, yaw_ratio: float | None = None
                     ) -> str:
    """The vehicle file's [actuators] lines for a fitted kf (TOML text)."""
    lines = ["[actuators]", f"# {comment}",
             f"kf = {kf:.4e}                         # N/(rad/s)^2",
             f"kf_se = {kf_se:.2e}                      # N/(rad/s)^2"]
    lines.append(f"yaw_ratio = {yaw_ratio}" if yaw_ratio is not None else
                 "yaw_ratio = 0.006                       # m: not measured here; give yours")
    lines.append("yaw_ratio_se = 0.0005                   # m")
    return "\n".join(lines)
