"""pinquad's known-mass regression beside sysid.tools (Eschmann, Albani and Loianno,
IROS 2024) on sysid.tools' own Crazyflie flights log10, log15 and log16: onboard IMU and
motor commands only, read as IMU-only micro-SD logs (``pinquad.io.imu_log``).

    python scripts/sysid_tools_side_by_side.py [DATA_DIR]

DATA_DIR: the folder with log10, log15, log16 (default: the sysid_tools folder next to
the Crazyflie data directory). Each number comes from the log sysid.tools takes it from:
the thrust curve and motor time constant from log10, I_xx and I_yy from log15, the yaw
coefficient or I_zz from log16 (on the torque band 0.5-3 Hz: ``BANDS``; pinquad fits
the curve and time constant of each log again: its inertia rests on that log's own
curve).

Two pinquad columns:

- under sysid.tools' assumptions: mass 0.027 kg, rotors at (+-0.028, +-0.028) m, M1
  front-right .. M4 front-left, yaw directions (-1, +1, -1, +1), its time ranges (log10
  35-65 s, log15 55-90 s, log16 32-38 s and 45-49 s). Its yaw coefficient K_tau [m] is
  then found as sysid.tools does: I_zz set to 1.832 x (I_xx + I_yy) / 2 (pinquad's I_xx,
  I_yy), and K_tau = I_zz / (I_zz / K_tau), the ratio the log16 yaw regression fixes;
- with the vehicle's real geometry: the shipped ``crazyflie21`` file (0.0325 m per axis,
  the 0.046 m arm; yaw ratio 0.006 +- 0.0005 m, so I_zz is identified), mass 0.027 kg,
  the time ranges pinquad finds itself (the logs' flight segments).

Every pinquad number carries its total standard error and verdict. sysid.tools gives no
uncertainty. Its loader scales acc.z by 9.18 instead of 9.81, which lowers its thrust
curve by 6.4 %; pinquad reads acc.z x 9.81.
"""

from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path

from pinquad.core.actuator_curve import read_curve_vehicle
from pinquad.core.vehicle_file import load_vehicle
from pinquad.identification.excitation import segments_of
from pinquad.identification.known_mass import (
    KnownMassResult,
    KnownMassSettings,
    identify_known_mass,
)
from pinquad.identification.verdict import NOT_ADEQUATE, NOT_IDENTIFIABLE, TRUSTED, Estimate
from pinquad.io.datadir import checkout_data_dir
from pinquad.io.read import read_command_log

CF21 = load_vehicle("crazyflie21").actuators
"""The shipped Crazyflie 2.1 file's actuators (its yaw ratio, given for the real geometry)."""

MASS = 0.027
"""sysid.tools' assumed mass [kg] (the Crazyflie 2.x nominal take-off mass)."""
LEVER = 0.028
"""sysid.tools' rotor offset per axis [m]."""
INERTIA_RATIO = 1.832
"""sysid.tools' I_zz / ((I_xx + I_yy) / 2)."""
RANGES = {"log10": [(35.0, 65.0)], "log15": [(55.0, 90.0)],
          "log16": [(32.0, 38.0), (45.0, 49.0)]}
"""sysid.tools' time ranges [s, the log's clock]."""
BANDS = {"log10": (0.3, 2.0), "log15": (0.3, 2.0), "log16": (0.5, 3.0)}
"""pinquad's torque band per log [Hz]: the default 0.3-2 Hz needs 13 s of flight (four
periods of its low edge); log16 has 10 s in sysid.tools' ranges and 12 s of flight
segments, so its yaw is read on 0.5-3 Hz (8 s needed)."""
SYSID = {"curve": (0.02127, -0.01118, 0.12013), "quadratic": 0.1500,
         "I_xx": 1.029e-5, "I_yy": 1.105e-5, "I_zz": 1.955e-5, "K_tau": 0.00179}
"""What sysid.tools' notebook reports (its saved outputs): per-motor thrust c0 + c1 u +
c2 u^2 [N] and the pure quadratic [N], inertia [kg m^2], its assumed I_zz, the yaw
coefficient K_tau [m]."""


def assumptions_vehicle(folder: Path) -> Path:
    """A vehicle file of sysid.tools' model: rotors M1..M4 at (+x, -y), (-x, -y), (-x, +y),
    (+x, +y) with x = y = 0.028 m, yaw directions (-1, +1, -1, +1); the yaw ratio 1 m, so
    that the I_zz the yaw regression reports is I_zz / K_tau [kg m]."""
    rotors = [(LEVER, -LEVER, -1), (-LEVER, -LEVER, 1), (-LEVER, LEVER, -1), (LEVER, LEVER, 1)]
    text = ('name = "sysid_tools_crazyflie"\n[body]\nmass = 0.027\n'
            "inertia = [1.029e-5, 1.105e-5, 1.955e-5]\n"
            "[actuator_curve]\ncommand_range = [0, 65535]\nyaw_ratio = 1.0\n"
            "yaw_ratio_se = 1e-12\n"
            + "".join(f"\n[[rotor]]\nx = {x!r}\ny = {y!r}\nspin = {s}\n" for x, y, s in rotors))
    path = folder / "sysid_tools_crazyflie.toml"
    path.write_text(text)
    return path


def fit(data: Path, name: str, vehicle: Path, ranges) -> KnownMassResult:
    """pinquad's known-mass regression of one log on ``ranges`` (None: its flight
    segments)."""
    cv = read_curve_vehicle(vehicle)
    settings = KnownMassSettings(band=BANDS[name])
    segs, _ = segments_of(read_command_log(data / name), ranges, settings.band)
    drag = cv.spec.aero.drag
    return identify_known_mass(segs, MASS, cv.spec.positions, cv.spec.spin, cv.curve,
                               settings, drag_z=None if drag is None else float(drag[2]))


def cell(e: Estimate | None, scale: float = 1.0) -> str:
    """value +- total se (verdict), both times ``scale``."""
    if e is None or not math.isfinite(e.value):
        return "- " + ("" if e is None else f"({e.verdict})")
    return f"{e.value * scale:.4g} +- {e.stderr * scale:.2g} ({e.verdict})"


def get(result: KnownMassResult, name: str) -> Estimate | None:
    return next((e for e in result.estimates if e.name == name), None)


def yaw_coefficient(rates: KnownMassResult, yaw: KnownMassResult) -> Estimate:
    """sysid.tools' K_tau from pinquad's numbers: I_zz = 1.832 (I_xx + I_yy) / 2 from
    ``rates`` and I_zz / K_tau from ``yaw`` (regressed with K_tau = 1); relative errors
    in quadrature; the worst of the three verdicts, and over 10 % total not
    identifiable."""
    ixx, iyy, ratio = get(rates, "I_xx"), get(rates, "I_yy"), get(yaw, "I_zz")
    assert ixx is not None and iyy is not None and ratio is not None
    mean = (ixx.value + iyy.value) / 2.0
    mean_se = math.hypot(ixx.stderr, iyy.stderr) / 2.0
    value = INERTIA_RATIO * mean / ratio.value
    rel = math.hypot(mean_se / mean, ratio.stderr / ratio.value)
    order = (TRUSTED, NOT_IDENTIFIABLE, NOT_ADEQUATE)
    verdict = max((ixx.verdict, iyy.verdict, ratio.verdict), key=order.index)
    if rel > 0.10 and verdict == TRUSTED:
        verdict = NOT_IDENTIFIABLE
    return Estimate("K_tau", value, "m", value * rel, (("combined", value * rel),), verdict)


def main(data: Path | None = None) -> None:
    data = data or checkout_data_dir().parent / "sysid_tools"
    with tempfile.TemporaryDirectory() as tmp:
        theirs = assumptions_vehicle(Path(tmp))
        a = {name: fit(data, name, theirs, RANGES[name]) for name in RANGES}
    b = {name: fit(data, name, Path("crazyflie21"), None) for name in RANGES}
    c0, c1, c2 = SYSID["curve"]
    lines = [f"{'quantity':<28} {'sysid.tools':>14}   {'pinquad, its assumptions':<40} "
             "pinquad, real geometry (crazyflie21)", "-" * 130]

    def row(label: str, theirs_text: str, left: str, right: str) -> None:
        lines.append(f"{label:<28} {theirs_text:>14}   {left:<40} {right}")

    for tag, res in (("its assumptions", a["log10"]), ("real geometry", b["log10"])):
        u = next(n for n in res.notes if n.startswith("mean command"))
        lines.insert(0, f"log10 {tag}: {u}; the curve explains {res.force_share * 100:.1f} % "
                        "of the vertical force")
    u_m = a["log10"].mean_command
    row("thrust c_1 [N] (log10)", f"{c1:.5f}", cell(get(a["log10"], "thrust c_1")),
        cell(get(b["log10"], "thrust c_1")))
    row("thrust c_2 [N] (log10)", f"{c2:.5f}", cell(get(a["log10"], "thrust c_2")),
        cell(get(b["log10"], "thrust c_2")))
    row(f"thrust at u={u_m:.3f} [N]", f"{c0 + c1 * u_m + c2 * u_m * u_m:.5f}",
        cell(get(a["log10"], "thrust at mean u")), cell(get(b["log10"], "thrust at mean u")))
    row(f"dT/du at u={u_m:.3f} [N]", f"{c1 + 2 * c2 * u_m:.5f}",
        cell(get(a["log10"], "dT/du at mean u")), cell(get(b["log10"], "dT/du at mean u")))
    row("motor time constant [ms]", "not stated", cell(get(a["log10"], "time constant"), 1e3),
        cell(get(b["log10"], "time constant"), 1e3))
    for name in ("I_xx", "I_yy"):
        row(f"{name} [1e-6 kg m^2] (log15)", f"{SYSID[name] * 1e6:.2f}",
            cell(get(a["log15"], name), 1e6), cell(get(b["log15"], name), 1e6))
    row("yaw K_tau [1e-3 m] (log16)", f"{SYSID['K_tau'] * 1e3:.2f}",
        cell(yaw_coefficient(a["log15"], a["log16"]), 1e3),
        f"{CF21.yaw_ratio * 1e3:g} +- {CF21.yaw_ratio_se * 1e3:g} (given: crazyflie21.toml)")
    row("I_zz [1e-6 kg m^2] (log16)", f"{SYSID['I_zz'] * 1e6:.2f} (set)",
        f"{INERTIA_RATIO} x mean(I_xx, I_yy) (set)", cell(get(b["log16"], "I_zz"), 1e6))
    print("\n".join(lines))
    print("\nwhy not trusted:")
    for tag, runs in (("its assumptions", a), ("real geometry", b)):
        for name, res in runs.items():
            for e in res.estimates:
                if e.verdict != TRUSTED and e.reasons:
                    print(f"  {tag}, {name}, {e.name}: {e.reasons[0]}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else None)
