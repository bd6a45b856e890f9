"""Discovery's settings and results: ``DiscoveryConfig``, ``CandidateScore``, the data of
the report's figures (``EffectEvidence``) and ``DiscoveryResult`` (the report.json
``discovery`` section). The method is in ``pinquad.discovery.discover``'s docstring."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from estimators.protocol import Posterior
from pinquad.core.effect_vocabulary import EFFECT_NAMES
from pinquad.core.params import VehicleRange
from pinquad.discovery.library import SPECS, domain_text, lower_bounds
from pinquad.models.ssm import Theta

Array = NDArray[np.float64]

AXES = ("force_x", "force_y", "force_z", "torque_x", "torque_y", "torque_z")
"""The body-wrench residual rows rho_k = Y_k pi - tau_k [N (force), N m (torque)]."""
ATT_AXES = ("att_rate_x", "att_rate_y", "att_rate_z")
"""The attitude-kinematics residual (Theta_{k+1} - Theta_k)/dt - E^{-1}(Theta_k) omega_k
[rad/s] of the smoothed means, per Euler angle (roll, pitch, yaw)."""
GYRO_AXES = ("gyro_x", "gyro_y", "gyro_z")
"""The gyro measurement residual y_gyro,k - omega_k|N [rad/s], per body axis."""


@dataclass(frozen=True)
class DiscoveryConfig:
    """Settings of the discovery loop.

    block_seconds [s]: length of the alternating train/held-out blocks;
    window_seconds [s]: averaging window of the reported residual RMS;
    min_heldout_gain [-]: minimum relative held-out SSE reduction on the candidate's rows
    (calibrated on clean flights, see ``python -m pinquad.discovery``);
    max_effects: stop after this many; candidates: effect names searched;
    refit_passes: coefficient/EM alternations of the refit; em_iterations: E-steps per EM
    run of the refit (at most; the compiled E-step covers ``QuadSSM`` and ``EffectSSM``);
    restart_em: start the refit EM from the paper's warm-up (fixed Q0/R0) rather than
    the base fit's noise, which absorbed the missing effect (a refit that kept it and ran
    10 E-steps left drag flights' held-out force residual at 2.4x a clean flight's; one
    that kept the base fit's measurement noise with the joint fit's wrench noise took 119
    instead of 174 E-steps on the benchmark's log but left the refit inertia of the
    discovery Monte Carlo worse, e.g. ground effect's I_zz 3.48 % RMS instead of 2.61 %:
    docs/benchmark.md, "Discovery in a minute");
    full_refit: also refit on all transitions for the reported estimates (else the
    training-block refit is reported); refit_em: False skips the EM refit (mass and
    coefficients fitted on the base posterior's force rows with the base inertia held:
    measured flights, whose inertia comes from a band-limited M-step, and quick checks);
    joint_iterations, joint_tol: after the passes, at most this many single-E-step
    updates of coefficients and parameters together, until the coefficients change by
    less than joint_tol (relative; ``pinquad.discovery.refit``);
    sampling_nuisance: the nuisance columns of ``pinquad.discovery.residuals.
    sampling_columns`` (the change of the known wrench within a logged interval) that
    every model the selection compares carries (not the coefficients' fit), by index (0:
    the thrust direction's move on the body x/y force rows, 1: the vertical force row;
    not 2, the torque rows: docs/discovery.md, "Actuation between samples", says why; ()
    for none, the default: a log whose input was held over each interval, as pinquad's
    simulator's, has no such change; ``discovery.calibrated.discovery_config`` turns them
    on for sampled logs);
    two_fold: score each candidate on both folds (even blocks train and odd are held
    out, then the other way round) and sum the evidence (``selection.score_candidate``);
    False: the even-block fold alone, the earlier rule (an effect whose signal sat
    in the odd blocks, such as a flight's one low pass over the floor, failed BIC on the
    training blocks while its held-out gain was 45-84 %);
    min_lag_intervals: a ``motor_lag`` whose time constant is below this many log
    intervals dt is not selected. Over one interval a first-order lag of tau << dt only
    moves the interval's mean input by about -(tau / dt) (u_{k+1} - u_k): a small
    multiple of the input's change across the interval, which the input's unknown
    course between two logged samples gives as well, so the log cannot tell such a lag
    from how its actuation was sampled (on flightgen's floor-strike and clean flights a
    0.16-0.7 ms "lag" at 4-10 ms intervals passed every other test);
    min_lag_seconds [s]: nor one below this time constant, at any log rate. A motor's
    time constant is tens of milliseconds (the Crazyflie's 30 ms; small brushless motors
    10-20 ms); a lag of a millisecond or two is the timing of the commands themselves: a
    controller's zero-order hold (half its period: 0.25 ms at 2 kHz, 1 ms at 500 Hz) and
    the radio or ESC update. On flightgen's 500 Hz logs, whose 2 kHz controller holds
    each command for 0.5 ms, 0.3-0.8 ms "lags" passed every other test beside the
    injected drag, ground effect or wind (added after those runs); search: the range
    the refit's EM searches mass and inertia in (``identification.search_range``; None:
    unbounded).
    """

    block_seconds: float = 2.0
    window_seconds: float = 0.1
    min_heldout_gain: float = 0.10
    max_effects: int = 3
    candidates: tuple[str, ...] = EFFECT_NAMES
    refit_passes: int = 2
    em_iterations: int = 100
    restart_em: bool = True
    full_refit: bool = True
    refit_em: bool = True
    joint_iterations: int = 60
    joint_tol: float = 1e-3
    sampling_nuisance: tuple[int, ...] = ()
    two_fold: bool = True
    min_lag_intervals: float = 0.25
    min_lag_seconds: float = 0.002
    search: VehicleRange | None = None


DEFAULT_CONFIG = DiscoveryConfig()
"""The default settings (frozen: safe as a shared argument default)."""


@dataclass(frozen=True)
class CandidateScore:
    """One candidate's test in one round.

    gain: relative held-out SSE reduction on its rows [-]; d_loglik_heldout: held-out
    Gaussian log-likelihood gain [nats]; d_bic: training 2 dJ - p log n (> 0 passes);
    coefficients: fitted on the training blocks. With ``DiscoveryConfig.two_fold`` each
    is over both folds (the SSEs and the gains summed, the coefficients averaged).
    """

    effect: str
    round: int
    gain: float
    d_loglik_heldout: float
    d_bic: float
    coefficients: tuple[float, ...]
    passed: bool


@dataclass(frozen=True)
class ScatterSeries:
    """One series of a scatter panel: label (a residual axis), x (n,) and y (n,) in the
    panel's units."""

    label: str
    x: Array
    y: Array


@dataclass(frozen=True)
class ScatterPanel:
    """One panel of an effect's figure: title, axis labels (with units) and its series."""

    title: str
    x_label: str
    y_label: str
    series: tuple[ScatterSeries, ...]


@dataclass(frozen=True)
class EffectEvidence:
    """What the report draws for one selected effect (``pinquad.discovery.evidence``): the
    held-out residual of its main rows against its explaining feature, before (base
    model) and after (refit with the effects)."""

    effect: str
    before: ScatterPanel
    after: ScatterPanel


STDERR_NOTE = ("stderr = the larger of the block jackknife at the refit posterior (which "
               "holds the smoothed states fixed) and the observed information of the EKF "
               "likelihood in the coefficients, mass, inertia and noise held at the refit's "
               "(which does not); NaN information: the jackknife alone")


def _by_name(names: Sequence[str], values: Array | None) -> dict[str, float] | None:
    if values is None:
        return None
    return {n: float(v) for n, v in zip(names, values, strict=True)}


@dataclass(frozen=True)
class DiscoveryResult:
    """What discovery found.

    selected: effect names in the order found; coefficients / stderr: name -> (p,) in the
    units of ``pinquad.discovery.library.SPECS``; stderr: the larger of stderr_jackknife
    (block jackknife at the refit posterior) and stderr_information (observed information
    of the EKF likelihood; ``pinquad.discovery.uncertainty``); scores: every
    candidate test of every round; rms_before / rms_after: held-out residual RMS per axis
    (``AXES`` [N, N m], ``GYRO_AXES`` [rad/s], ``ATT_AXES`` [rad/s]); mass [kg], inertia
    (3, 3) [kg m^2]: after the refit (the base estimates if nothing was selected); theta:
    refit parameters; posterior: its E-step; validation: how before/after was measured;
    evidence: one per selected effect, the data of its figure; figures: paths of the
    figures drawn from it (set by ``pinquad.report.discovery.draw_discovery_figures``;
    empty until drawn); coefficients_alternation: name -> (p,) the refit's coefficients
    before the Newton step to their likelihood's maximum (``uncertainty.information_fit``;
    empty without an EM refit) and likelihood_step_gain [nats] what that step gained (0:
    none taken); coefficients_free: name -> (p,) for the effects with a coefficient on
    its domain's edge (``pinquad.discovery.domain``), their fit without the domain at the
    same posterior (the reported coefficients are the fit inside it).
    """

    selected: tuple[str, ...]
    coefficients: dict[str, Array]
    stderr: dict[str, Array]
    scores: tuple[CandidateScore, ...]
    rms_before: dict[str, float]
    rms_after: dict[str, float]
    mass: float
    inertia: Array
    theta: Theta
    posterior: Posterior
    validation: str
    evidence: tuple[EffectEvidence, ...] = field(default_factory=tuple)
    figures: tuple[str, ...] = field(default_factory=tuple)
    stderr_jackknife: dict[str, Array] = field(default_factory=dict)
    stderr_information: dict[str, Array] = field(default_factory=dict)
    coefficients_alternation: dict[str, Array] = field(default_factory=dict)
    likelihood_step_gain: float = 0.0
    coefficients_free: dict[str, Array] = field(default_factory=dict)

    def to_report(self) -> dict:
        """report.json's ``discovery`` section (plus candidate scores and refit estimates)."""
        selected = []
        for name in self.selected:
            spec = SPECS[name]
            best = [s for s in self.scores if s.effect == name and s.passed][-1]
            selected.append({
                "effect": name,
                "coefficients": {n: float(v) for n, v in zip(spec.coefficient_names,
                                                              self.coefficients[name], strict=True)},
                "stderr": {n: float(v) for n, v in zip(spec.coefficient_names,
                                                        self.stderr[name], strict=True)},
                "stderr_jackknife": _by_name(spec.coefficient_names,
                                             self.stderr_jackknife.get(name)),
                "stderr_observed_information": _by_name(spec.coefficient_names,
                                                        self.stderr_information.get(name)),
                "coefficients_before_likelihood_step": _by_name(
                    spec.coefficient_names, self.coefficients_alternation.get(name)),
                "units": dict(zip(spec.coefficient_names, spec.units, strict=True)),
                "domain": domain_text(name),
                "on_domain_edge": [n for n, c, b in zip(spec.coefficient_names,
                                                        self.coefficients[name],
                                                        lower_bounds(name), strict=True)
                                   if c <= b],
                "coefficients_without_domain": _by_name(spec.coefficient_names,
                                                        self.coefficients_free.get(name)),
                "evidence": {"heldout_gain": best.gain, "d_loglik_heldout": best.d_loglik_heldout,
                             "d_bic_train": best.d_bic, "round": best.round,
                             "rows": [AXES[r] for r in spec.rows] or list(GYRO_AXES)},
            })
        return {
            "selected": selected,
            "residual_rms_before": dict(self.rms_before),
            "residual_rms_after": dict(self.rms_after),
            "validation": self.validation,
            "stderr_note": STDERR_NOTE,
            "likelihood_step_gain": self.likelihood_step_gain,
            "candidates": [{"effect": s.effect, "round": s.round, "heldout_gain": s.gain,
                            "d_loglik_heldout": s.d_loglik_heldout, "d_bic_train": s.d_bic,
                            "selected": s.passed} for s in self.scores],
            "refit": {"mass": self.mass, "inertia": np.asarray(self.inertia).tolist()},
            "figures": list(self.figures),
        }
