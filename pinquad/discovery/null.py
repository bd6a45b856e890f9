"""Effect selection calibrated against the null: does a selected effect's evidence beat
what the fitted base model itself produces on this log?

Discovery's selection (``pinquad.discovery.discover``) tests each candidate by its
held-out gain, BIC and held-out likelihood. Those tests assume the base model describes
the data up to white noise; a log whose sampling, trajectory or noise the base model
does not describe (a controller faster than its log, a smooth trajectory, coloured
noise) produces evidence for effects that are not there. The calibration measures that
directly, by a parametric bootstrap:

1. fly ``replicates`` shadow flights of the base fit (``pinquad.sim.shadow``): the base
   model with the fitted mass, inertia and noise, along the log's smoothed trajectory,
   integrated at a fine rate with a fine-rate controller, logged like the log (its
   length, rate, channels, gaps; the commands sampled at the log instants);
2. on each, smooth with the base model (the E-step of the fit) and score every selected
   effect exactly as the selection's first round does (``selection.score_candidate``
   against the base model): its null gain g*_r;
3. the effect's p-value is p = (1 + #{r: g*_r >= g}) / (1 + replicates) against its own
   first-round gain g on the log; it is kept when p <= ``alpha`` (with 19 replicates and
   alpha 0.05: its gain beats every shadow flight's).

A shadow flight contains no effect, so each replicate in which a candidate passes the
selection's own tests is a measured false positive of the uncalibrated selection on
flights like this one (``null_passes``).

A base fit whose inertia lies outside what the vehicle can physically be (a base model
that cannot explain the log, such as a centre of mass off the rotor plane's centre, can
drive its inertia to 3e-7 or 1e77 kg m^2) is no null to fly: its shadow flights leave the
path or break down, and every effect would lose to NaN gains. The shadow flights then
fly, and are scored with, the nearest plausible base model: the inertia diagonal clipped
into the vehicle's range (``plausible_base_fit``). The null hypothesis stays "no effect, the
base model with physically possible parameters"; the report says when it was clipped.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from estimators.protocol import Posterior
from pinquad.discovery.discover import Selection
from pinquad.discovery.residuals import compute_residuals
from pinquad.discovery.result import DiscoveryConfig, DiscoveryResult
from pinquad.discovery.selection import base_fits, score_candidate
from pinquad.estep.fast_smoother import smooth_quad
from pinquad.models.ssm import Observations, QuadSSM, Theta
from pinquad.sim.shadow import ShadowSettings, shadow_flight

Array = NDArray[np.float64]


@dataclass(frozen=True)
class NullSettings:
    """replicates: shadow flights per log (0: no calibration); seed: of the numpy
    Generator that draws them; alpha: largest p-value an effect may have to be kept;
    shadow: how shadow flights are flown."""

    replicates: int = 19
    seed: int = 0
    alpha: float = 0.05
    shadow: ShadowSettings = field(default_factory=ShadowSettings)

    def __post_init__(self) -> None:
        if self.replicates < 0:
            raise ValueError(f"null replicates must be >= 0; got {self.replicates}")
        if not 0.0 < self.alpha < 1.0:
            raise ValueError(f"alpha must be in (0, 1); got {self.alpha}")
        if 0 < self.replicates < round(1.0 / self.alpha) - 1:
            raise ValueError(f"{self.replicates} null replicates cannot give p <= {self.alpha:g} "
                             f"(the smallest p is 1 / (1 + replicates)); use at least "
                             f"{round(1.0 / self.alpha) - 1}")


@dataclass(frozen=True)
class NullCalibration:
    """The null calibration of one log's selected effects (module docstring).

    observed: effect -> its first-round held-out gain on the log [-]; null_gains:
    effect -> (replicates,) its gains on the shadow flights [-]; null_passes: effect ->
    shadow flights on which it passed the uncalibrated selection; p_value: effect -> p;
    kept / rejected: the effects that beat / did not beat the null; tracking_rms [m]:
    RMS distance of the shadow flights from the log's smoothed path; seconds: wall time;
    flown_inertia (3,) [kg m^2] or None: the inertia diagonal the shadow flights flew
    when the base fit's lay outside the vehicle's range (``plausible_base_fit``), else None.
    """

    replicates: int
    seed: int
    alpha: float
    observed: dict[str, float]
    null_gains: dict[str, Array]
    null_passes: dict[str, int]
    p_value: dict[str, float]
    kept: tuple[str, ...]
    rejected: tuple[str, ...]
    tracking_rms: float
    seconds: float
    flown_inertia: Array | None = None

    def to_report(self) -> dict:
        """The ``null_calibration`` entry of report.json's ``discovery`` section."""
        return {
            "method": ("parametric bootstrap: shadow flights of the base fit along the log's "
                       "smoothed path, logged like the log (pinquad.discovery.null)"),
            "replicates": self.replicates, "seed": self.seed, "alpha": self.alpha,
            "effects": {e: {"heldout_gain": self.observed[e],
                            "null_gain_max": float(np.max(self.null_gains[e])),
                            "null_gain_median": float(np.median(self.null_gains[e])),
                            "null_passes": self.null_passes[e],
                            "p_value": self.p_value[e],
                            "kept": e in self.kept} for e in self.observed},
            "rejected": list(self.rejected),
            "shadow_tracking_rms_m": self.tracking_rms,
            "shadow_tracking_note": (
                "the shadow flights stayed within 10 cm (RMS) of the log's path"
                if self.tracking_rms <= 0.1 else
                "the shadow flights strayed more than 10 cm (RMS) from the log's path: the "
                "null is a flight unlike this one, read its p-values with care"),
            "seconds": self.seconds,
            "shadow_inertia_note": (
                None if self.flown_inertia is None else
                "the base fit's inertia lies outside the vehicle's range; the shadow flights "
                "fly its nearest point in that range, diag ("
                + ", ".join(f"{1e6 * v:.3g}" for v in self.flown_inertia) + ") e-6 kg m^2"),
        }


def first_round_gains(result: DiscoveryResult | Selection) -> dict[str, float]:
    """effect -> its first-round held-out gain (against the base model alone) in
    ``result``'s candidate scores (a discovery's or its selection's), for the selected
    effects."""
    return {s.effect: s.gain for s in result.scores
            if s.round == 0 and s.effect in result.selected}


@dataclass(frozen=True)
class ShadowScoring:
    """One shadow flight to score (picklable for a worker process): its observations,
    the base fit ``theta`` it was flown with, the effects to score and the settings."""

    obs: Observations
    theta: Theta
    effects: tuple[str, ...]
    cfg: DiscoveryConfig


def score_shadow(job: ShadowScoring) -> tuple[list[float], list[bool]]:
    """Smooth a shadow flight with the base model and score each effect as the
    selection's first round does: (gains, passed) in the order of ``job.effects``."""
    theta, cfg = job.theta, job.cfg
    post = smooth_quad(QuadSSM(job.obs, theta), job.obs.ys)
    res = compute_residuals(job.obs, post, theta.gravity, cfg.block_seconds)
    train = np.arange(res.n_blocks) % 2 == 0
    pi0 = np.r_[theta.mass, np.diag(theta.inertia)]
    base = (base_fits(res, [], pi0, cfg, train) if any(e != "gyro_bias" for e in job.effects)
            else None)
    scores = [score_candidate(res, [], e, pi0, 0, cfg, train, base) for e in job.effects]
    return [s.gain for s in scores], [bool(s.passed) for s in scores]


def plausible_base_fit(theta: Theta, inertia_bounds: tuple[Array, Array] | None) -> Theta:
    """The base fit the shadow flights fly, and the selection's fits and the refit start
    from (``discovery.calibrated.discover_calibrated``): ``theta`` itself when its inertia
    diagonal lies within ``inertia_bounds`` = (lo (3,), hi (3,)) [kg m^2] (or there are none), else
    ``theta`` with the inertia diag(J') = diag(clip(diag I, lo, hi)) (products of inertia
    dropped: they belong to the implausible tensor) and the torque noise intensities
    S'_tau,i = S_tau,i min((J'_i / I_ii)^2, 1) [N^2 m^2 s]: neither the torque noise nor
    the angular-acceleration noise S_tau,i / I_ii^2 larger than the fit's. With the fit's
    S_tau at an inertia 900 times smaller the shadow flights' filter broke down (flightgen
    500 Hz flight 3003); with the fit's angular-acceleration noise at an inertia 14 times
    larger they strayed 3.6 m from the path (flight 3007). A fixed process noise (the
    paper's Q0) is kept."""
    if inertia_bounds is None:
        return theta
    lo, hi = (np.asarray(b, dtype=float) for b in inertia_bounds)
    diag = np.diag(np.asarray(theta.inertia, dtype=float))
    if np.all(np.isfinite(diag)) and np.all((diag >= lo) & (diag <= hi)):
        return theta
    clipped = np.clip(np.nan_to_num(diag, nan=np.sqrt(lo * hi)), lo, hi)
    noise = theta.noise
    if noise.fixed_q is None:
        wrench = np.asarray(noise.wrench, dtype=float).copy()
        ratio = np.divide(clipped, diag, out=np.ones(3), where=np.isfinite(diag) & (diag > 0))
        wrench[3:6] = wrench[3:6] * np.minimum(ratio**2, 1.0)
        noise = replace(noise, wrench=wrench)
    return replace(theta, inertia=np.diag(clipped), noise=noise)


def calibrate(obs: Observations, theta: Theta, posterior: Posterior, observed: dict[str, float],
              cfg: DiscoveryConfig, settings: NullSettings = NullSettings(),
              actuation: str = "held", executor: Executor | None = None,
              inertia_bounds: tuple[Array, Array] | None = None) -> NullCalibration:
    """Calibrate effects against shadow flights of the base fit (``theta``, ``posterior``:
    the base EM result on ``obs``; module docstring). observed: effect -> its first-round
    held-out gain on the log (``first_round_gains``); actuation: the log's, ``held`` or
    ``sampled`` (``LogMeta.actuation``): the shadow flights are logged the same way;
    executor: where the shadow flights are smoothed and scored (``score_shadow``; None:
    here, one after another); inertia_bounds: the vehicle's physically possible inertia
    diagonal (lo (3,), hi (3,)) [kg m^2], into which an implausible base fit is clipped
    before it is flown (``plausible_base_fit``; None: flown as fitted). The flights themselves
    are flown here, in order, from one Generator, so the answer does not depend on the
    executor."""
    start = time.perf_counter()
    flown = plausible_base_fit(theta, inertia_bounds)
    theta_is_fit = flown is theta
    theta = flown
    observed = dict(observed)
    effects = list(observed)
    rng = np.random.default_rng(settings.seed)
    gains: dict[str, list[float]] = {e: [] for e in effects}
    passes = dict.fromkeys(effects, 0)
    sq_dist = []
    pending = []
    for _ in range(settings.replicates):
        shadow = shadow_flight(obs, theta, posterior.mean, rng, settings.shadow, actuation)
        sq_dist.append(np.mean(np.sum((shadow.states[:, 0:3] - posterior.mean[:, 0:3]) ** 2,
                                      axis=1)))
        job = ShadowScoring(shadow.obs, theta, tuple(effects), cfg)
        pending.append(executor.submit(score_shadow, job) if executor is not None
                       else score_shadow(job))
    for item in pending:
        shadow_gains, shadow_passed = item.result() if executor is not None else item
        for e, g, ok in zip(effects, shadow_gains, shadow_passed, strict=True):
            gains[e].append(g)
            passes[e] += int(ok)
    null_gains = {e: np.asarray(v, dtype=float) for e, v in gains.items()}
    # a shadow flight whose gain could not be scored (NaN) counts against the effect
    p_value = {e: float((1 + np.sum(~(null_gains[e] < observed[e]))) / (1 + settings.replicates))
               for e in effects}
    kept = tuple(e for e in effects if p_value[e] <= settings.alpha)
    rejected = tuple(e for e in effects if e not in kept)
    tracking = float(np.sqrt(np.mean(sq_dist))) if sq_dist else float("nan")
    return NullCalibration(settings.replicates, settings.seed, settings.alpha, observed,
                           null_gains, passes, p_value, kept, rejected, tracking,
                           time.perf_counter() - start,
                           None if theta_is_fit else np.diag(theta.inertia).copy())


def combine(calibrations: Sequence[NullCalibration]) -> NullCalibration:
    """One calibration of every effect the calibrations in turn tested (the effects of
    later ones were selected after the earlier ones' rejections; same settings)."""
    first = calibrations[0]
    observed: dict[str, float] = {}
    null_gains: dict[str, Array] = {}
    passes: dict[str, int] = {}
    p_value: dict[str, float] = {}
    for cal in calibrations:
        observed.update(cal.observed)
        null_gains.update(cal.null_gains)
        passes.update(cal.null_passes)
        p_value.update(cal.p_value)
    return NullCalibration(first.replicates, first.seed, first.alpha, observed, null_gains,
                           passes, p_value, tuple(e for c in calibrations for e in c.kept),
                           tuple(e for c in calibrations for e in c.rejected),
                           float(np.nanmax([c.tracking_rms for c in calibrations])),
                           float(sum(c.seconds for c in calibrations)),
                           next((c.flown_inertia for c in calibrations
                                 if c.flown_inertia is not None), None))
