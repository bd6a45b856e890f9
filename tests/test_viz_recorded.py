"""What a recorded log's run adds for the viewer, on known answers: the residual size per
step, the EM iterates' layouts, whether a log names its vehicle, and the view of a run
whose log named none (a hand-written run directory; the real-browser view of a real
flight is tests/test_viz.py::test_recorded_log_view_in_browser)."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from estimators.protocol import Posterior
from pinquad.core.params import CRAZYFLIE21
from pinquad.experiments.step_residuals import window_mean, wrench_residuals
from pinquad.io.logs import FlightLog, read_table, write_log
from pinquad.io.runs import REPORT_SCHEMA
from pinquad.models.ssm import Observations
from pinquad.report.run_tables import EM_HISTORY_COLUMNS, em_history_rows, em_iterates

G = 9.81


def _hover(n: int, thrust: float, torque: np.ndarray, exclude: np.ndarray | None = None
           ) -> tuple[Observations, Posterior]:
    mean = np.zeros((n, 12))
    mean[:, 2] = 1.0
    inputs = np.tile(np.r_[thrust, torque], (n, 1))
    obs = Observations(t=0.01 * np.arange(n), dt=0.01, inputs=inputs, channels=("pos",),
                       ys=mean[:, 0:3].copy(), x0=mean[0], p0=np.ones(12),
                       exclude=np.zeros(0, bool) if exclude is None else exclude)
    post = Posterior(mean, np.zeros((n, 12, 12)), np.zeros((n - 1, 12, 12)), 0.0, "rts",
                     np.zeros((n, 3), bool))
    return obs, post


def test_wrench_residual_of_a_hover_is_the_thrust_and_torque_surplus():
    """At rest, Y pi = [0, 0, m g, 0, 0, 0]: the residual is m g - F on the z force and
    minus the logged torque; excluded transitions and the last step are NaN."""
    m, inertia = 0.035, np.array([1.6e-5, 1.7e-5, 2.9e-5])
    exclude = np.zeros(6, bool)
    exclude[2] = True
    obs, post = _hover(6, m * G + 0.01, np.array([0.0, 2e-6, 0.0]), exclude)
    rho = wrench_residuals(obs, post, G, np.r_[m, inertia])
    assert np.isnan(rho[[2, 5]]).all()
    ok = [0, 1, 3, 4]
    np.testing.assert_allclose(rho[ok], np.tile([0, 0, -0.01, 0, -2e-6, 0], (4, 1)), atol=1e-12)
    # effects that are not a linear wrench are left out of it
    rho_bias = wrench_residuals(obs, post, G, np.r_[m, inertia], {"gyro_bias": np.ones(3)})
    np.testing.assert_array_equal(rho_bias, rho)


def test_window_mean_skips_missing_rows():
    values = np.array([[1.0], [np.nan], [3.0], [np.nan], [np.nan], [np.nan]])
    np.testing.assert_allclose(window_mean(values, 3)[:, 0],
                               [1.0, 2.0, 3.0, 3.0, np.nan, np.nan])


def _run(history_mass, loglik, e_steps=None, mstep="regressor"):
    hm = np.asarray(history_mass, float)
    return SimpleNamespace(history_mass=hm, history_inertia=np.column_stack([hm] * 3),
                           loglik=np.asarray(loglik, float), e_steps=e_steps, mstep=mstep,
                           sensor="pos", iterations=len(loglik))


def test_em_iterates_align_the_log_likelihood_with_each_layout():
    # one iterate per log-likelihood (the simulated path)
    p, ll = em_iterates(_run([1, 2, 3], [10, 20, 30]))
    np.testing.assert_array_equal(ll, [10, 20, 30])
    # the initial guess first, then one per log-likelihood (measured flights)
    p, ll = em_iterates(_run([1, 1, 2, 3], [10, 20, 30]))
    np.testing.assert_array_equal(p[:, 0], [1, 1, 2, 3])
    np.testing.assert_array_equal(ll, [np.nan, 10, 20, 30])
    # the ten-parameter fit keeps only its start and end
    p, ll = em_iterates(_run([1, 4], [10, 20, 30, 40], mstep="full"))
    np.testing.assert_array_equal(p[:, 0], [1, np.nan, np.nan, 4])
    np.testing.assert_array_equal(ll, [10, 20, 30, 40])
    rows = em_history_rows([_run([1, 1, 2], [10, 20], e_steps=7)])
    assert len(rows) == 3 and all(len(r) == len(EM_HISTORY_COLUMNS) for r in rows)
    assert [r[3] for r in rows] == [0, 1, 2] and {r[-1] for r in rows} == {7}


def _tiny_log(n: int = 20) -> FlightLog:
    t = 0.01 * np.arange(n)
    z = np.zeros((n, 3))
    return FlightLog(t=t, position=z, velocity=z, euler=z, gyro=z, accel=z,
                     thrust=np.full(n, 0.3), torque=z)


def test_whether_a_log_names_its_vehicle(tmp_path: Path):
    path = write_log(_tiny_log(), tmp_path / "flight.csv")
    sidecar = Path(f"{path}.json")
    assert read_table(path).meta.vehicle_named  # write_log's sidecar names it
    sidecar.write_text(json.dumps({"mass_guess": 0.03}))
    assert not read_table(path).meta.vehicle_named
    sidecar.unlink()
    meta = read_table(path).meta
    assert not meta.vehicle_named and meta.vehicle == "paper"


def test_view_of_a_log_that_names_no_vehicle(tmp_path: Path):
    """The header says the log named no vehicle; a Crazyflie-sized quad of the identified
    33 g is drawn (the stand-in nearest in mass, scaled by the cube root of the mass
    ratio), at its real size; the EM history and headline come from the run's files."""
    from viz.app import serve
    from viz.geometry import body_radius, vehicle_parts
    from viz.panels import header_markdown
    from viz.scene import urdf_for

    (tmp_path / "logs").mkdir()
    write_log(_tiny_log(), tmp_path / "logs" / "flight.csv")
    note = ("vehicle not named by the log: drawn at the size of a 33.0 g quad (the "
            "identified mass); give the vehicle in the log's sidecar")
    verdict = {"overall": "trusted", "reasons": [],
               "parameters": {n: {"verdict": "trusted", "reasons": []}
                              for n in ("mass", "I_xx", "I_yy", "I_zz")}}
    est = {"mass": 0.033, "inertia": np.diag([1.6e-5, 1.7e-5, 2.9e-5]).tolist(),
           "stderr": {"mass": 1e-4, "inertia_diag": [1e-7, 1e-7, 2e-7]}, "verdict": verdict,
           "model": "base rigid-body model"}
    rows = ["run,sensor,mstep,iterate,mass,I_xx,I_yy,I_zz,loglik,e_steps"]
    rows += [f"0,B,regressor,{k},{0.001 + 0.032 * k / 4},1e-4,2e-4,1e-4,"
             f"{'' if k == 0 else 100 * k},4" for k in range(5)]
    (tmp_path / "logs" / "em_history.csv").write_text("\n".join(rows) + "\n")
    report = {"schema": REPORT_SCHEMA,
              "source": {"kind": "log", "vehicle": "paper", "vehicle_named": False,
                         "vehicle_note": note},
              "estimates": est, "base": est, "verdict": verdict, "reference": None,
              "runs": [{"sensor": "B", "mstep": "regressor", "estimates": est, "e_steps": 4}],
              "run_logs": {"log": {"log": "logs/flight.csv",
                                   "em_history": "logs/em_history.csv"}}}
    (tmp_path / "report.json").write_text(json.dumps(report))
    v = serve(tmp_path, port=0)
    try:
        assert v.scale == 1.0
        assert "vehicle not named by the log: drawn at the size of a 33.0 g quad" in (
            header_markdown(v.run, v.scale))
        assert "paper" not in header_markdown(v.run, v.scale)
        cf = vehicle_parts(urdf_for("crazyflie21"))
        assert body_radius(v.parts) == pytest.approx(
            body_radius(cf) * (0.033 / CRAZYFLIE21.mass) ** (1 / 3))
        rec = v.run.cycles[0]
        assert rec.e_steps == 4 and rec.x.shape == (5,)
        np.testing.assert_allclose(v.loglik_plot.data[1], [np.nan, 100, 200, 300, 400])
        assert "4 E-steps" in v.param_table.content
        head = v.headline_text.content
        assert "33.000 ± 0.100" in head and "base fit" not in head and "trusted" in head
        assert v.colour_dropdown is None  # no residual table: no selector
    finally:
        v.stop()


def test_report_says_when_the_log_names_no_vehicle():
    from pinquad.io.logs import LogMeta
    from pinquad.report.run_tables import reference, vehicle_note

    unnamed = SimpleNamespace(log=SimpleNamespace(meta=LogMeta(vehicle_named=False)))
    named = SimpleNamespace(log=SimpleNamespace(meta=LogMeta(vehicle="crazyflie21")))
    assert vehicle_note(unnamed, 0.0331).startswith(
        "vehicle not named by the log: drawn at the size of a 33.1 g quad")
    assert vehicle_note(named, 0.0331) is None
    assert reference("crazyflie21")["mass"] == CRAZYFLIE21.mass and reference("paper") is None
