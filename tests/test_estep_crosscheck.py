"""The two E-steps against each other on the quadcopter (issue 4): the GTSAM batch
smoother (MAP trajectory and its Laplace marginals, ``estimators.factor_graph``) and the
EKF + RTS smoother (``estimators.rts``, compiled as ``pinquad.estep.fast_smoother``), on
simulated flights of sensors A, B and C with the true mass and inertia and realistic
structured noise; then EM with either E-step, and the offline command with
``--estep gtsam``.

What holds, and what does not:

* For every sensor the MAP's negative log-posterior J is at most that of the RTS means,
  and RTS run on the model linearised about the MAP (Q_k frozen there, as in GTSAM's last
  Gauss-Newton step) reproduces GTSAM's mean to within the solver's own bound
  sqrt(2 * decrement) posterior std and its covariances and lag-one cross-covariances to
  1e-8 (of std_i std_j). So both implementations solve the same factor graph; whatever
  separates them is where the model is linearised.
* Sensor B (attitude measured): the EKF's linearisation points are already good, the
  posterior is nearly Gaussian, and the two agree at every step to a few thousandths of a
  posterior std (the criterion is 0.1) with covariance diagonals equal to about 1e-4
  (criterion 10 %); J(MAP) is below J(RTS means) by a few hundredths of a nat.
* Sensors A and C (no attitude measurement): the criterion of 0.1 std and 10 % fails,
  over the whole log, not in an initial transient (seed 1, rows 60..659: at most 1.1
  std for A and 3.3 std for C, still 0.6 and 1.5 std after the first 150 steps;
  covariance diagonals up to 56 % and 190 % apart). Yaw is then seen only through the
  direction of the thrust (posterior std about 0.12 rad) and roll, pitch and yaw are
  coupled nonlinearly through it, while the prior on the attitude is diffuse (0,
  1 rad^2). The EKF linearises each step at its filtered mean, commits early to a yaw
  that the tiny attitude process noise then carries through the log, and RTS cannot
  move the linearisation points afterwards. The MAP is the better answer: J lower by
  about 1.5e3 (A) and 1.2e4 (C) nats; GTSAM started from the RTS means ends at the same
  MAP (1e-12 std apart when this was written); its yaw is closer to the truth (RTS
  0.053 rad off for A and 0.136 for C, MAP 0.021 and 0.032; seed 2, rows 60..859,
  sensor A: RTS 1.12 rad off, MAP 0.06). With an informative attitude prior (the true
  initial Euler angles, variance 1e-2 rad^2) the J gap falls to about 12 nats, but the
  means still differ by 0.3 (A) and 0.55 (C) std: the yaw-tilt posterior stays
  curved. The strict test is therefore an expected failure for A and C (strict, and
  only on an AssertionError, so it reports if that changes); the linearisation test
  above is what shows that the difference is the EKF's and not a bug.
* Iterating the RTS smoother (``estimators.iterated``: EKF + RTS on the model
  linearised about the last smoothed trajectory, a Gauss-Newton step per pass) moves
  the linearisation points to the MAP; it then meets the 0.1 std / 10 % criterion for
  every sensor, A and C included (a few 1e-4 std apart when this was written).

EM with the GTSAM E-step and with the compiled RTS E-step reach the same mass and
inertia (sensor B) to a small fraction of a standard error, and the command line runs
with the GTSAM E-step.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np
import pytest

from estimators import factor_graph as fg
from estimators import iterated, rts
from estimators.factor_graph import SolveInfo
from estimators.iterated import LinearisedAbout
from estimators.protocol import Array, Posterior
from pinquad.core.conventions import wrap_angle
from pinquad.core.params import PAPER_INITIAL_INERTIA, PAPER_INITIAL_MASS
from pinquad.estep.fast_smoother import smooth_quad
from pinquad.identification import em, fisher
from pinquad.models import sources
from pinquad.models.ssm import NoiseModel, Observations, QuadSSM, Theta
from pinquad.mstep import updates as identify
from pinquad.mstep.protocol import REGRESSOR
from pinquad.sim import simulator as sim

ROOT = Path(__file__).resolve().parents[1]

SEED = 1
START = 60  # skip the floor contact and the take-off ramp at the start of the log
N_CROSS = 600  # steps of the smoother cross-check (6 s)
N_EM = 1000  # steps of the EM comparison (10 s)
EM_ITERATIONS = 8  # E-steps of each EM run (the same for both smoothers)

TRUE_MASS = 0.18
TRUE_INERTIA = np.diag([2.5e-4, 3.1e-4, 2.0e-4])
GRAVITY = 9.81
WRENCH_NOISE = np.array([1e-8, 1e-8, 4e-6, 4e-10, 4e-10, 4e-10])
MEAS_VAR = {"pos": 2.5e-5, "vel": 4e-4, "euler": 1e-4, "gyro": 2.25e-4}
EULER = slice(6, 9)

NO_ATTITUDE = pytest.mark.xfail(
    strict=True, raises=AssertionError,
    reason="no attitude measurement: the yaw-tilt posterior is curved and the EKF's "
           "linearisation points stay off the MAP for the whole log (module docstring)")
# E-steps of the command-line run: the GTSAM warm-up E-step on the force-free model and
# one on the full model. The asked-for 6 took 33-37 s alone on the loaded 2-core machine
# (13 s CPU), 2 take 21 s (8 s CPU); the fixed cost (imports, a 37 s flight, figures) is
# about 5 s CPU.
CLI_ITERATIONS = 2


@cache
def _flight(sensor: str) -> sim.Flight:
    return sim.simulate(sim.SimConfig(sensor=sensor), np.random.default_rng(SEED))


def _observations(sensor: str, n_steps: int) -> Observations:
    log = sim.flight_log(_flight(sensor)).slice(START, START + n_steps)
    return sources.observations(log, sensor)


def _true_theta(obs: Observations) -> Theta:
    meas = np.repeat([MEAS_VAR[ch] for ch in obs.channels], 3)
    noise = NoiseModel(wrench=WRENCH_NOISE, q_kin=identify.kinematic_floor(obs.dt), meas=meas)
    return Theta(TRUE_MASS, TRUE_INERTIA, noise, GRAVITY)


@dataclass(frozen=True)
class _Case:
    obs: Observations
    model: QuadSSM
    rts: Posterior
    gtsam: Posterior
    info: SolveInfo


@cache
def _case(sensor: str) -> _Case:
    obs = _observations(sensor, N_CROSS)
    model = QuadSSM(obs, _true_theta(obs))
    post, info = fg.smooth_with_info(model, obs.ys)
    return _Case(obs, model, rts.smooth(model, obs.ys), post, info)


def _mean_difference(a: Array, b: Array) -> Array:
    """a - b (N, 12) with the Euler rows wrapped to (-pi, pi]."""
    d = np.array(a - b, dtype=float)
    d[:, EULER] = wrap_angle(d[:, EULER])
    return d


def _parameters(theta: Theta) -> Array:
    """[m, I_xx, I_yy, I_zz]."""
    return np.concatenate([[theta.mass], np.diag(theta.inertia)])


def _compiled_loglik(model: QuadSSM, ys: Array) -> float:
    """log p(y | theta) from the compiled EKF: the generic EKF's value (to rounding,
    tests/test_fast_smoother.py), fifteen times faster for the 33 evaluations of the
    observed information."""
    return smooth_quad(model, ys).loglik


# ----------------------------------------------------------------------------- E-step


@pytest.mark.parametrize("sensor", ["A", "B", "C"])
def test_map_has_the_lower_negative_log_posterior(sensor):
    case = _case(sensor)
    j_map = fg.negative_log_posterior(case.model, case.obs.ys, case.gtsam.mean)
    j_rts = fg.negative_log_posterior(case.model, case.obs.ys, case.rts.mean)
    assert j_map == pytest.approx(case.info.cost_history[-1], rel=1e-12)
    assert np.all(np.diff(case.info.cost_history) < 0.0)
    assert j_map <= j_rts
    # the compiled EKF + RTS is the generic one on this model too
    fast = smooth_quad(case.model, case.obs.ys)
    np.testing.assert_allclose(fast.mean, case.rts.mean, rtol=0.0,
                               atol=1e-9 * float(np.abs(case.rts.mean).max()))
    np.testing.assert_allclose(fast.cov, case.rts.cov, rtol=1e-7,
                               atol=1e-9 * float(np.abs(case.rts.cov).max()))


@pytest.mark.parametrize("sensor", ["A", "B", "C"])
def test_rts_of_the_map_linearisation_is_gtsam(sensor):
    """Both smoothers solve the same factor graph: RTS on the model linearised about the
    MAP gives GTSAM's answer, the mean to the Gauss-Newton bound sqrt(2 * decrement)
    posterior std (SolveInfo) and the covariances to rounding."""
    case = _case(sensor)
    assert case.info.decrement < 1e-5, case.info.reason
    post = case.gtsam
    lin = rts.smooth(LinearisedAbout(case.model, post.mean), case.obs.ys)
    bound = math.sqrt(2.0 * case.info.decrement)
    assert np.all(np.abs(_mean_difference(lin.mean, post.mean))
                  <= (bound * (1.0 + 1e-6) + 1e-9) * post.std)
    scale = post.std[:, :, None] * post.std[:, None, :]
    assert np.max(np.abs(lin.cov - post.cov) / scale) < 1e-8
    cross_scale = post.std[1:, :, None] * post.std[:-1, None, :]
    assert np.max(np.abs(lin.cross_cov - post.cross_cov) / cross_scale) < 1e-8


@pytest.mark.parametrize("sensor", [
    pytest.param("A", marks=NO_ATTITUDE),
    "B",
    pytest.param("C", marks=NO_ATTITUDE),
])
def test_gtsam_and_ekf_rts_agree_within_a_tenth_of_a_std(sensor):
    """At every step, every state: |mean_gtsam - mean_rts| <= 0.1 RTS posterior std
    (Euler rows wrapped) and the marginal variances within 10 %."""
    case = _case(sensor)
    z = np.abs(_mean_difference(case.gtsam.mean, case.rts.mean)) / case.rts.std
    worst = np.unravel_index(np.argmax(z), z.shape)
    assert z.max() <= 0.1, f"step {worst[0]}, state {worst[1]}: {z.max():.3f} std"
    var_g, var_r = case.gtsam.std ** 2, case.rts.std ** 2
    rel = np.abs(var_g - var_r) / var_r
    worst = np.unravel_index(np.argmax(rel), rel.shape)
    assert rel.max() <= 0.1, f"step {worst[0]}, state {worst[1]}: {rel.max():.3f}"


@pytest.mark.parametrize("sensor", ["A", "B", "C"])
def test_gtsam_and_iterated_rts_agree_within_a_tenth_of_a_std(sensor):
    """The issue's criterion with the RTS smoother iterated (``estimators.iterated``: EKF
    + RTS re-run on the model linearised about the last smoothed trajectory, stopping at
    a step of 1e-3 std): at every step, every state, |mean_gtsam - mean_ieks| <= 0.1
    posterior std and marginal variances within 10 %, for every sensor; the lag-one
    cross-covariances too. Two independent solvers of the same MAP problem agree; on A
    and C they agree to a few 1e-4 std."""
    case = _case(sensor)
    post, info = iterated.smooth_with_info(case.model, case.obs.ys)
    assert info.converged, info.reason
    assert info.cost_history[-1] <= info.cost_history[0]
    z = np.abs(_mean_difference(case.gtsam.mean, post.mean)) / post.std
    worst = np.unravel_index(np.argmax(z), z.shape)
    assert z.max() <= 0.1, f"step {worst[0]}, state {worst[1]}: {z.max():.3f} std"
    var_g, var_i = case.gtsam.std ** 2, post.std ** 2
    assert np.max(np.abs(var_g - var_i) / var_i) <= 0.1
    cross_scale = post.std[1:, :, None] * post.std[:-1, None, :]
    assert np.max(np.abs(post.cross_cov - case.gtsam.cross_cov) / cross_scale) <= 0.1
    j_ieks = fg.negative_log_posterior(case.model, case.obs.ys, post.mean)
    assert j_ieks == pytest.approx(case.info.cost_history[-1], abs=1e-3)


# ----------------------------------------------------------------------------- EM


@pytest.mark.parametrize("sensor", ["A", "B", "C"])
def test_em_with_the_gtsam_and_the_rts_e_step_agree(sensor):
    """10 s of flight, from 0.8 m and 0.7 I: the same EM settings with either E-step
    (GTSAM's MAP smoother and the single-pass compiled EKF + RTS) reach the same (m, I)
    to 0.5 standard error (observed information at the RTS estimate), at every
    iteration; for A and C too, where the two smoothers' state means differ by up to
    1.1 and 3.3 std (measured: within 0.007 standard error)."""
    obs = _observations(sensor, N_EM)
    theta0 = em.initial_theta(obs, 0.8 * TRUE_MASS, 0.7 * TRUE_INERTIA, GRAVITY)
    runs = {name: em.run_em(obs, theta0, smoother, REGRESSOR,
                            max_iterations=EM_ITERATIONS)
            for name, smoother in (("gtsam", fg.smooth), ("rts", smooth_quad))}
    assert runs["gtsam"].e_steps == runs["rts"].e_steps == EM_ITERATIONS
    se = fisher.standard_errors(fisher.observed_information(obs, runs["rts"].theta,
                                                            _compiled_loglik))
    assert np.all(np.isfinite(se)) and np.all(se > 0.0)
    diff = _parameters(runs["gtsam"].theta) - _parameters(runs["rts"].theta)
    assert np.all(np.abs(diff) <= 0.5 * se), diff / se
    history = {name: np.column_stack([r.mass, r.inertia_diag]) for name, r in runs.items()}
    assert history["gtsam"].shape == history["rts"].shape
    assert np.all(np.abs(history["gtsam"] - history["rts"]) <= 0.5 * se)
    # both moved from the start towards the truth
    start_error = np.abs(_parameters(theta0) - _parameters(_true_theta(obs)))
    assert np.all(np.abs(_parameters(runs["rts"].theta) - _parameters(_true_theta(obs)))
                  < 0.5 * start_error)


# ----------------------------------------------------------------------------- command


def _offline_command(estep: str, out: Path) -> dict:
    proc = subprocess.run(
        [sys.executable, "-m", "pinquad.offline", "--estep", estep, "--cycles", "1",
         "--sensor", "B", "--mstep", "regressor", "--no-information",
         "--max-iterations", str(CLI_ITERATIONS), "--jobs", "1", "--out", str(out)],
        capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return json.loads((out / "report.json").read_text())


@pytest.fixture(scope="module")
def rts_command_estimates(tmp_path_factory) -> np.ndarray:
    """[m, I_xx, I_yy, I_zz] of the same command with the RTS E-step (the reference)."""
    report = _offline_command("rts", tmp_path_factory.mktemp("rts") / "run")
    (cycle,) = report["cycles"]
    return np.r_[cycle["estimates"]["mass"], np.diag(cycle["estimates"]["inertia"])]


@pytest.mark.parametrize("estep", ["gtsam", "ieks"])
def test_offline_command_with_the_map_e_steps(tmp_path, estep, rts_command_estimates):
    report = _offline_command(estep, tmp_path / "run")
    assert report["source"]["estep"] == estep
    assert report["em"]["iterations"] >= 1
    # the estimates: EM from the paper's start (m0 = 1 g, I0) did not lower the
    # likelihood and, after CLI_ITERATIONS E-steps, is nearer the truth than its start
    (cycle,) = report["cycles"]
    assert cycle["sensor"] == "B" and cycle["mstep"] == "regressor"
    loglik = np.asarray(cycle["em"]["loglik"])
    assert loglik.size == CLI_ITERATIONS and np.all(np.diff(loglik) >= -1e-9 * np.abs(loglik[1:]))
    est = np.r_[cycle["estimates"]["mass"], np.diag(cycle["estimates"]["inertia"])]
    truth = np.r_[TRUE_MASS, np.diag(TRUE_INERTIA)]
    start = np.r_[PAPER_INITIAL_MASS, np.diag(np.asarray(PAPER_INITIAL_INERTIA))]
    assert np.all(np.isfinite(est)) and np.all(est > 0)
    assert np.all(np.abs(est - truth) < np.abs(start - truth)), (est, start)
    assert cycle["estimates"] == report["estimates"]
    # and it is the RTS E-step's answer: the MAP smoothers' state means agree with RTS's
    # within a tenth of a standard deviation on these flights (tests above), and from the
    # same start the same E-steps reach the same estimates (measured 1e-11 (gtsam) and
    # 1.4e-8 (ieks) relative apart on this run); 1e-6 leaves a hundredfold margin
    np.testing.assert_allclose(est, rts_command_estimates, rtol=1e-6)


@pytest.fixture(scope="module")
def simulated_offline(tmp_path_factory):
    """``python -m pinquad.offline`` in its simulated mode with the default M-steps
    (``--mstep both``: regressor and the paper's), one sensor-B cycle."""
    out = tmp_path_factory.mktemp("offline") / "run"
    proc = subprocess.run(
        [sys.executable, "-m", "pinquad.offline", "--cycles", "1", "--sensor", "B", "--jobs",
         "1", "--no-information", "--out", str(out)],
        capture_output=True, text=True, cwd=ROOT, timeout=900)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    report = json.loads((out / "report.json").read_text())
    assert report["source"]["msteps"] == ["regressor", "paper"]
    cycles = {c["mstep"]: c for c in report["cycles"]}
    assert set(cycles) == {"regressor", "paper"}
    return report, cycles


def _relative_errors(cycle) -> Array:
    est = np.r_[cycle["estimates"]["mass"], np.diag(cycle["estimates"]["inertia"])]
    truth = np.r_[cycle["truth"]["mass"], np.diag(cycle["truth"]["inertia"])]
    np.testing.assert_allclose(truth, np.r_[TRUE_MASS, np.diag(TRUE_INERTIA)])
    return (est - truth) / truth


def test_simulated_offline_command_regressor_estimates(simulated_offline):
    """docs/paper.md's bounds: mass within 0.2 % and every inertia entry within 3 % of
    the truth (regressor M-step, every cycle); EM converged and did not lower the
    likelihood."""
    report, cycles = simulated_offline
    cyc = cycles["regressor"]
    assert cyc["sensor"] == "B" and cyc["em"]["converged"]
    loglik = np.asarray(cyc["em"]["loglik"])
    assert np.all(np.diff(loglik) >= -1e-9 * np.abs(loglik[1:]))
    err = _relative_errors(cyc)
    assert abs(err[0]) <= 0.002, err
    assert np.all(np.abs(err[1:]) <= 0.03), err
    assert report["estimates"] == cyc["estimates"]


def test_simulated_offline_command_paper_mstep(simulated_offline):
    """The paper's M-step, which the default command runs beside ours: mass within
    0.2 % (docs/paper.md: both M-steps), inertia within its documented worst on sensor B
    (7.3 / 6.3 / 14.9 %, docs/paper.md), a different estimate from the regressor's on the
    same log (it is a different M-step), and its statistics row in the report."""
    report, cycles = simulated_offline
    cyc = cycles["paper"]
    assert cyc["sensor"] == "B" and cyc["seed"] == cycles["regressor"]["seed"]
    err = _relative_errors(cyc)
    assert abs(err[0]) <= 0.002, err
    assert np.all(np.abs(err[1:]) <= [0.073, 0.063, 0.149]), err
    assert np.all(np.abs(err - _relative_errors(cycles["regressor"])) > 1e-4)
    rows = [r for r in report["statistics"] if r["mstep"] == "paper"]
    assert [r["param"] for r in rows] == ["mass", "Ixx", "Iyy", "Izz"]
    np.testing.assert_allclose([r["max_rel_err"] for r in rows], np.abs(err), rtol=1e-9)


@pytest.mark.xfail(strict=True, reason="the paper's M-step misses the 3 % inertia target: "
                   "measured -5.0 / -5.0 / -14.3 % (I_xx / I_yy / I_zz, sensor B, seed 0); "
                   "docs/paper.md: up to 14.9 %, |bias| > std in all 9 cases")
def test_simulated_offline_command_paper_mstep_inertia_target(simulated_offline):
    """The project's inertia target (3 %, docs/paper.md) for the paper's M-step."""
    _, cycles = simulated_offline
    assert np.all(np.abs(_relative_errors(cycles["paper"])[1:]) <= 0.03)
