"""The shared IMRC Crazyflie logs read as IMU-only (accelerometer, gyro, motor PWM and
battery kept; pose, velocity and rotor speeds left out, ``pinquad.io.imu_log``) and
identified with the mass on the scale given (34.7 g) by the known-mass regression,
beside the full-log answers (motion capture and measured rotor speeds: the EM pipeline's
I_xx and I_yy with their total errors, docs/realdata.md's table).

    python scripts/imrc_imu_only.py [LOG ...]

Each log is fitted on its flight segments with the torque band 0.3-2 Hz, or 1-5 Hz when
its flight is shorter than the 13 s the lower band needs. Prints per log and axis the
IMU-only value +- total se (verdict), the full-log value +- total se, and their distance
in combined total errors; then the counts.
"""

from __future__ import annotations

import math
import sys

from pinquad.core.actuator_curve import read_curve_vehicle
from pinquad.identification.excitation import segments_of
from pinquad.identification.known_mass import KnownMassSettings, identify_known_mass
from pinquad.io.datadir import checkout_data_dir
from pinquad.io.read import read_command_log

MASS = 0.0347
"""The vehicle on the scale [kg] (the data set's README)."""
FULL_LOG = {
    "jana00": ((16.2, 1.1), (17.0, 1.3)), "jana01": ((16.6, 1.5), (16.7, 1.2)),
    "jana02": ((18.8, 2.4), (17.2, 3.7)), "jana03": (None, (21.2, 2.5)),
    "jana04": ((16.5, 1.1), (17.0, 0.9)), "jana05": ((15.2, 0.9), (16.2, 0.9)),
    "jana10": ((17.2, 1.2), (17.5, 1.1)), "jana20": ((17.8, 1.8), (17.3, 1.4)),
    "jana23": ((16.2, 2.2), (15.0, 1.4)), "jana24": ((17.8, 2.1), (17.0, 1.7)),
    "jana25": ((16.0, 1.6), (15.4, 1.2)), "jana27": ((18.4, 2.2), (16.9, 1.9)),
    "jana28": ((18.3, 2.0), (16.2, 1.5)), "jana29": ((15.9, 1.6), (16.0, 1.4)),
}
"""The full-log I_xx, I_yy [e-6 kg m^2] +- total se of ``python -m pinquad.realdata``
(docs/realdata.md's table: motion capture, measured rotor speeds, the thrust stand's kf,
jana20-29 with M1 rebuilt from PWM); None: not trusted there (no error bar)."""
SHORT_BAND = (1.0, 5.0)


def main(names: list[str]) -> None:
    vehicle = read_curve_vehicle("crazyflie21")
    counts = {"within": 0, "trusted": 0, "trusted_within": 0, "pairs": 0}
    for name in names:
        flight = read_command_log(checkout_data_dir() / "imrc_brushed" / name)
        settings = KnownMassSettings()
        segs, _ = segments_of(flight, None, settings.band)
        span = sum(float(s.log.t[-1]) for s in segs)
        if span < 4.0 / settings.band[0]:
            settings = KnownMassSettings(band=SHORT_BAND)
        res = identify_known_mass(segs, MASS, vehicle.spec.positions, vehicle.spec.spin,
                                  vehicle.curve, settings)
        cells = []
        for axis, full in zip(("I_xx", "I_yy"), FULL_LOG[name], strict=True):
            e = res.get(axis)
            text = f"{axis} {e.value * 1e6:.2f} +- {e.stderr * 1e6:.2f} ({e.verdict})"
            if full is not None:
                z = abs(e.value * 1e6 - full[0]) / math.hypot(e.stderr * 1e6, full[1])
                text += f" vs full {full[0]} +- {full[1]}: {z:.1f} combined se"
                counts["pairs"] += 1
                counts["within"] += z <= 2.0
                counts["trusted"] += e.verdict == "trusted"
                counts["trusted_within"] += e.verdict == "trusted" and z <= 2.0
            cells.append(text)
        print(f"{name} ({span:.1f} s, band {settings.band[0]:g}-{settings.band[1]:g} Hz, "
              f"curve explains {res.force_share * 100:.0f} %): " + "; ".join(cells))
    print(f"\n{counts['pairs']} pairs: {counts['within']} within 2 combined total se of the "
          f"full-log answer; {counts['trusted']} trusted, {counts['trusted_within']} of them "
          "within 2 combined se")


if __name__ == "__main__":
    main(sys.argv[1:] or list(FULL_LOG))
