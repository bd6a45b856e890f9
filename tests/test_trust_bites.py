"""The trust machinery against expectations worked out here, not read from the code under
test: the error budget of a Crazyflie flight by hand (the between-flight model error read
from the vehicle file with tomllib, the yaw part scaled by I_zz), the "settled" rule of an
unconverged EM on hand-built iterates, the headline's mass-balance comparison through the
function the headline calls, and a run directory rerun after a real killed attempt
(docs/tests.md, scripts/mutation_check.py: each of these tests fails under a named
one-line break)."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import tomllib
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from pinquad.identification.budget import Calibration, calibration_of, error_budget
from pinquad.identification.identify import Identification, unconverged
from pinquad.identification.verdict import (
    NOT_ADEQUATE,
    NOT_IDENTIFIABLE,
    TRUSTED,
    VerdictEvidence,
    judge,
    vehicle_range,
)
from pinquad.io.logs import LogMeta
from pinquad.io.runs import RunWriter
from pinquad.pipeline.judge import fit_evidence, with_budget

REPO = Path(__file__).resolve().parents[1]
CRAZYFLIE_FILE = REPO / "pinquad" / "data" / "crazyflie21.toml"

# A Crazyflie flight's estimate and statistical errors, round numbers of jana00's
# (mass 34.7 g; I_zz 30e-6 kg m^2 with a 5e-6 statistical error: its yaw sweep is short)
VALUES = np.array([0.0347, 16.0e-6, 17.0e-6, 30.0e-6])
STATISTICAL = np.array([0.08e-3, 0.3e-6, 0.5e-6, 5.0e-6])
THRUST_REL, YAW_REL = 0.05, 0.10


def _crazyflie_meta() -> LogMeta:
    """The sidecar of a log that names the shipped Crazyflie 2.1 (as a micro-SD log does)."""
    return LogMeta(vehicle="crazyflie21", vehicle_named=True, source="jana00",
                   actuation="sampled")


def test_crazyflie_budget_worked_by_hand():
    """The budget of p = [m, I_xx, I_yy, I_zz] with kf 5 %, yaw ratio 10 % and the
    vehicle file's arm and between-flight model error (read here with tomllib: 2.2 %;
    0.3, 6.6, 7.5, 35.5 %), part by part and in total, by hand. I_zz:
    statistical 5.0, thrust 30 * 0.05 = 1.5, yaw 30 * 0.10 = 3.0, between flights
    30 * 0.355 = 10.65 (e-6 kg m^2): total sqrt(25 + 2.25 + 9 + 113.4225) = 12.234e-6.
    Its +-2 total standard errors cover 4 * 12.234 / (117.0 - 7.32) = 44.6 % of the
    Crazyflie's I_zz range: not identifiable, as jana00's headline is; without the
    between-flight part (6.02e-6: 22 %) it would read trusted."""
    shipped = tomllib.loads(CRAZYFLIE_FILE.read_text())["uncertainty"]
    model_error = np.array(shipped["model_error"], dtype=float)
    np.testing.assert_array_equal(model_error, [0.003, 0.066, 0.075, 0.355])
    cal = calibration_of(_crazyflie_meta(), (THRUST_REL, YAW_REL))
    np.testing.assert_array_equal(cal.model_error, model_error)
    assert (cal.thrust, cal.yaw_torque, cal.arm) == (THRUST_REL, YAW_REL, shipped["arm"])
    budget = error_budget(VALUES, STATISTICAL, cal)
    parts = budget.parts
    np.testing.assert_allclose(parts["between_flights"],
                               [0.1041e-3, 1.056e-6, 1.275e-6, 10.65e-6], rtol=1e-12)
    np.testing.assert_allclose(parts["yaw_torque_coefficient"], [0.0, 0.0, 0.0, 3.0e-6],
                               rtol=1e-12, atol=0.0)
    np.testing.assert_allclose(parts["thrust_calibration"],
                               [1.735e-3, 0.80e-6, 0.85e-6, 1.5e-6], rtol=1e-12)
    np.testing.assert_allclose(parts["arm_length"], [0.0, 0.352e-6, 0.374e-6, 0.0],
                               rtol=1e-12, atol=0.0)
    izz_total = math.sqrt(5.0**2 + 1.5**2 + 3.0**2 + 10.65**2) * 1e-6
    assert izz_total == pytest.approx(12.234e-6, rel=1e-4)
    mass_total = math.sqrt(0.08**2 + 1.735**2 + 0.1041**2) * 1e-3
    np.testing.assert_allclose(budget.total[[0, 3]], [mass_total, izz_total], rtol=1e-12)

    vrange = vehicle_range("crazyflie21")
    share = 4.0 * izz_total / (vrange.inertia_hi[2] - vrange.inertia_lo[2])
    assert share > 0.40
    verdict = judge(VALUES[0], np.diag(VALUES[1:]), budget.total, VerdictEvidence(), vrange)
    assert verdict.get("I_zz").verdict == NOT_IDENTIFIABLE
    assert "cover 44.6 %" in verdict.get("I_zz").reasons[0]
    assert verdict.get("mass").verdict == TRUSTED


def test_a_yaw_budget_scales_with_i_zz_whatever_its_size():
    """The yaw torque coefficient's part is I_zz * r_yaw, a moment of inertia [kg m^2]:
    a 1000 times heavier vehicle's is 1000 times larger, a relative 10 % of its own I_zz
    (never the bare 0.10 of the relative uncertainty)."""
    cal = Calibration(thrust=0.0, yaw_torque=0.10, arm=0.0)
    for izz in (30.0e-6, 30.0e-3):
        budget = error_budget(np.array([1.0, 0.0, 0.0, izz]), np.zeros(4), cal)
        assert budget.parts["yaw_torque_coefficient"][3] == pytest.approx(0.1 * izz, rel=1e-12)
        assert budget.total[3] == pytest.approx(0.1 * izz, rel=1e-12)


def _run(history: np.ndarray, stat: np.ndarray) -> Identification:
    """An unconverged regressor run whose EM iterates were ``history`` (K, 4) of [m,
    I_xx, I_yy, I_zz], with statistical errors ``stat`` (4,)."""
    return Identification(
        mstep="regressor", mass=float(history[-1, 0]), inertia=np.diag(history[-1, 1:]),
        stderr=stat, history_mass=history[:, 0], history_inertia=history[:, 1:],
        loglik=np.zeros(len(history)), converged=False, e_steps=200)


def test_an_unconverged_fit_is_settled_only_when_every_parameter_is():
    """EM stopped at its E-step limit. Mass, I_xx, I_yy at their last values for three
    iterates (rest of the way 0); I_zz still steps by 1e-6, 0.9e-6, 0.81e-6 (rate 0.9:
    the rest of the way is 0.81e-6 * 0.9 / 0.1 = 7.3e-6, more than 0.1 of its 5e-6
    error): not settled, so not the likelihood's maximum, and no parameter is trusted.
    With I_zz's steps 1, 0.5, 0.25 e-9 (rest 0.25e-9) the same run has settled."""
    stat = STATISTICAL
    still = np.tile(VALUES, (4, 1))
    moving = still.copy()
    moving[:, 3] = VALUES[3] + np.array([0.0, 1.0e-6, 1.9e-6, 2.71e-6])
    run = _run(moving, stat)
    why = unconverged(run)
    assert why is not None and "did not converge" in why
    evidence = VerdictEvidence(**fit_evidence(SimpleNamespace(search=None), run))
    assert evidence.not_converged is not None
    verdict = judge(run.mass, run.inertia, stat, evidence, vehicle_range("crazyflie21"))
    assert verdict.get("mass").verdict == NOT_IDENTIFIABLE
    assert not verdict.trusted

    settled = still.copy()
    settled[:, 3] = VALUES[3] + np.array([0.0, 1.0e-9, 1.5e-9, 1.75e-9])
    assert unconverged(_run(settled, stat)) is None


def test_the_headline_compares_the_balance_with_the_unshared_mass_error():
    """``with_budget`` (what the headline hands the verdict) against a budget built here:
    the mass's statistical 0.08 g and input-reading 0.1 g are the reading's own, the 5 %
    thrust calibration (1.735 g) and the between-flight 0.3 % are shared with a
    model-free balance of the same thrust. The balance's comparison error is
    hypot(0.08, 0.1) = 0.1281 g; a balance 1.0 +- 0.1 g lighter is 1.0 / hypot(0.1281,
    0.1) = 6.2 combined errors away: model not adequate (against the total's 1.74 g it
    would hide inside 2 of them)."""
    cal = Calibration(THRUST_REL, YAW_REL, 0.022, np.array([0.003, 0.066, 0.075, 0.355]))
    held = VALUES + np.array([0.2e-3, 0.0, 0.0, 0.0])  # input part 0.1 g on the mass
    budget = error_budget(VALUES, STATISTICAL, cal, held_alternative=held)
    result = SimpleNamespace(log=SimpleNamespace(meta=_crazyflie_meta()))
    balance = (VALUES[0] - 1.0e-3, 0.1e-3)
    evidence = with_budget(VerdictEvidence(model_free_mass=balance), budget, result)
    assert evidence.balance_stderr == pytest.approx(math.hypot(0.08e-3, 0.1e-3), rel=1e-12)
    assert budget.total[0] > 1.7e-3  # what the balance must not be compared with
    verdict = judge(VALUES[0], np.diag(VALUES[1:]), budget.total, evidence, None)
    mass = verdict.get("mass")
    assert mass.verdict == NOT_ADEQUATE, mass.reasons
    assert any("model-free mass balance" in r and "6.2 combined" in r for r in mass.reasons)


KILLED_ATTEMPT = """
import sys, time
from pinquad.io.runs import RunWriter
writer = RunWriter(sys.argv[1], replace=True)
with writer:
    writer.path("report.json").write_text("half")
    writer.path("figures/residuals.png").write_text("from the killed attempt")
    print("written", flush=True)
    time.sleep(60)
"""


def test_a_rerun_after_a_killed_attempt_holds_only_its_own_files(tmp_path: Path):
    """A real attempt killed (SIGKILL: no clean-up runs) after it wrote a report and a
    figure; the rerun writes only its report. The published run holds the rerun's files
    and nothing of the killed attempt's; nothing is left beside it."""
    logs = tmp_path / "logs"
    target = logs / "jana00"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.Popen([sys.executable, "-c", KILLED_ATTEMPT, str(target)], env=env,
                            stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "written"
    finally:
        proc.send_signal(signal.SIGKILL)  # no clean-up handler can run
        proc.wait(timeout=30)
    # what the killed attempt left: its staging folder and its lock
    assert (logs / ".jana00.partial" / "figures" / "residuals.png").is_file()
    assert (logs / ".jana00.lock").is_file() and not target.exists()
    writer = RunWriter(target, replace=True)
    with writer:
        writer.path("report.json").write_text("rerun")
        final = writer.publish()
    assert final == target
    written = sorted(str(p.relative_to(target)) for p in target.rglob("*"))
    assert written == ["report.json"]
    assert (target / "report.json").read_text() == "rerun"
    assert sorted(p.name for p in logs.iterdir()) == ["jana00"]
