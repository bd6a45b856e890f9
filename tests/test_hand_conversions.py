"""Conversions checked against numbers worked by hand, not against the code's own
constants: a declared rad/s rotor speed and a log's uniform time step."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from pinquad.io.logs import read_table
from pinquad.io.timebase import uniform_step

RPM = (12000.0, 15000.0, 18000.0, 21000.0)
"""Rotor speeds [rev/min] of the hand-written log; the same in rad/s, worked by hand
with 1 rev/min = 2 pi / 60 rad/s: 12000 -> 400 pi, 15000 -> 500 pi, 18000 -> 600 pi,
21000 -> 700 pi."""
RAD_S = ("1256.6370614359173", "1570.7963267948965", "1884.9555921538758",
         "2199.1148575128555")


def _rotor_csv(path: Path, speeds: tuple[str, ...], rotor_speed: str | None) -> Path:
    header = "t,pos_x,pos_y,pos_z,rpm_1,rpm_2,rpm_3,rpm_4"
    rows = [f"{0.01 * k:.2f},0,0,1,{','.join(speeds)}" for k in range(60)]
    path.write_text("\n".join([header, *rows]) + "\n")
    side = {"vehicle": "crazyflie21", **({} if rotor_speed is None else
                                          {"rotor_speed": rotor_speed})}
    Path(f"{path}.json").write_text(json.dumps(side))
    return path


def test_declared_rad_per_s_matches_hand_converted_rpm(tmp_path):
    as_rad = read_table(_rotor_csv(tmp_path / "rad.csv", RAD_S, "rad/s"))
    as_rpm = read_table(_rotor_csv(tmp_path / "rpm.csv", tuple(f"{v:g}" for v in RPM), None))
    np.testing.assert_allclose(as_rad.rpm, np.tile(RPM, (60, 1)), rtol=1e-12)
    np.testing.assert_allclose(as_rpm.rpm, np.tile(RPM, (60, 1)), rtol=0)


def test_uniform_step_is_the_mean_of_the_steps_not_their_median():
    # steps 10, 10, 10, 13, 16 ms: median 10 ms, mean 59 / 5 = 11.8 ms (no gap: the
    # largest is below 4 x the median and below 20 ms)
    t = np.array([0.0, 0.010, 0.020, 0.030, 0.043, 0.059])
    assert abs(uniform_step(t) - 0.0118) < 1e-12
    # a 2 s gap is left out of the mean: (10 + 10 + 13 + 10) / 4 = 10.75 ms
    t = np.array([0.0, 0.010, 0.020, 0.033, 2.033, 2.043])
    assert abs(uniform_step(t) - 0.01075) < 1e-12
