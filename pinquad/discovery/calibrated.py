"""Effect discovery calibrated against the null: the selection of
``pinquad.discovery.discover`` whose every selected effect must beat shadow flights of
the base fit (``pinquad.discovery.null``) and fit inside its physical domain
(``pinquad.discovery.domain``), then the refit of the final selection.

It starts from a ``DiscoveryStart`` (observations, parameters, smoothed posterior of a
fit: ``discovery_start`` of a run) with the settings for the kind of log
(``discovery_config``) and gives a ``DiscoveryOutcome`` (the result, or why there is
none); the recorded-log pipeline (``pinquad.pipeline``) and the API call it through
``pinquad.pipeline.identify.run_discovery``.
"""

from __future__ import annotations

from concurrent.futures import Executor, Future
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from estimators.protocol import Posterior
from pinquad.discovery.discover import Selection, refit_selection, select_effects
from pinquad.discovery.domain import outside_domain, transition_heights, unexplained_residual
from pinquad.discovery.null import (
    NullCalibration,
    NullSettings,
    calibrate,
    combine,
    first_round_gains,
    plausible_base_fit,
)
from pinquad.discovery.result import DiscoveryConfig, DiscoveryResult
from pinquad.identification.identify import Identification
from pinquad.models.contact import FloorLevel
from pinquad.models.ssm import Observations, Theta, corrected

Array = NDArray[np.float64]


@dataclass(frozen=True)
class DiscoveryStart:
    """What effect discovery starts from: the observations the reported run's EM saw
    (measured flights: with its nuisance moment in the torques), its parameters and its
    smoothed posterior."""

    obs: Observations
    theta: Theta
    posterior: Posterior


def discovery_start(run: Identification) -> DiscoveryStart:
    """Where effect discovery starts from a run: its observations, parameters and
    posterior; a measured-flight run's nuisance block (``Theta.nuisance``) moves into the
    torques of its observations (``models.ssm.corrected``) and out of its parameters."""
    if run.posterior is None or run.observations is None or run.theta is None:
        raise ValueError("this identification kept no posterior to start discovery from")
    return start_from(run.observations, run.theta, run.posterior)


def start_from(obs: Observations, theta: Theta, posterior: Posterior) -> DiscoveryStart:
    """The ``DiscoveryStart`` of a fit: a measured-flight fit's nuisance block
    (``Theta.nuisance``) moved into the torques of its observations and out of its
    parameters (discovery's models add their effects to the rotor torques alone)."""
    return DiscoveryStart(corrected(obs, theta), theta.without_nuisance(), posterior)


@dataclass(frozen=True)
class DiscoveryOutcome:
    """Effect discovery on a log's reported run: its result, or why there is none (a
    numerical failure of the refit is reported, not raised: the identification stands
    without it), and the calibration of its selection against the null (None when
    nothing was selected or the calibration was switched off)."""

    result: DiscoveryResult | None
    error: str | None = None
    null: NullCalibration | None = None
    unphysical: tuple[dict, ...] = ()
    not_run: str | None = None
    note: str | None = None
    floor: FloorLevel | None = None

    def to_report(self) -> dict:
        """The ``discovery`` section of report.json; figure paths (if drawn) named
        relative to the run directory (``figures/<name>``); ``ground_effect_floor``: where
        the ground-effect law put the floor ({'height' [m], 'source', 'note'}; None when
        discovery did not reach the log)."""
        floor = None if self.floor is None else {
            "height": self.floor.height, "source": self.floor.source,
            "note": self.floor.describe()}
        if self.result is None:
            return {"selected": [], "residual_rms_before": {}, "residual_rms_after": {},
                    "validation": "not run", "error": self.error, "not_run": self.not_run,
                    "note": self.note, "unphysical": list(self.unphysical),
                    "ground_effect_floor": floor}
        section = self.result.to_report()
        section["ground_effect_floor"] = floor
        section["unphysical"] = list(self.unphysical)
        section["note"] = self.note
        section["not_run"] = None
        section["figures"] = [f"figures/{Path(f).name}" for f in section["figures"]]
        if self.null is not None:
            section["null_calibration"] = self.null.to_report()
            for entry in section["selected"]:
                entry["evidence"]["null_p_value"] = self.null.p_value.get(entry["effect"])
        else:
            section["null_calibration"] = {"replicates": 0, "note": (
                "nothing selected: no calibration needed" if not section["selected"]
                else "not calibrated against the null (--null-replicates 0)")}
        return section


DISCOVERY_SETTINGS: dict[str, dict] = {"sdlog": {"refit_em": False},
                                        "measured-table": {"refit_em": False}}
"""DiscoveryConfig overrides by log kind (``simulated``, ``sdlog``, ``measured-table``).
Measured flights keep the base inertia of ``realdata``'s band-limited M-step (the
plain regressor M-step of the EM refit does not hold it: on jana10 it moved I_xx from 17
to 24 e-6 kg m^2); their effects and the mass are fitted on the base posterior."""


SAMPLED_NUISANCE = (0,)
"""The sampling nuisance columns a log with sampled thrust and torque columns gets
(``DiscoveryConfig.sampling_nuisance``): the thrust direction's move within the interval
on the body x/y force rows. Not the vertical row's column 1 (mostly the thrust
magnitude's change), since the input reading takes the mean of the two rows' thrust:
there its expected coefficient is 0, and a free one (fitted -3 to -6 on gentle flightgen
flights) traded against drag's D_z, 5-25 % too high on minimum-snap flights
(docs/discovery.md)."""


def discovery_config(kind: str, actuation: str = "held") -> DiscoveryConfig:
    """Effect discovery's settings for a kind of log (``DISCOVERY_SETTINGS``) whose
    actuation (``LogMeta.actuation``) is ``held`` or ``sampled``: a log with sampled
    thrust and torque columns gets the sampling nuisance (``SAMPLED_NUISANCE``) in every
    model the selection compares; held logs and measured rotor-speed flights do not."""
    cfg = DiscoveryConfig(**DISCOVERY_SETTINGS.get(kind, {}))
    if kind == "simulated" and actuation == "sampled":
        cfg = replace(cfg, sampling_nuisance=SAMPLED_NUISANCE)
    return cfg


def discover_calibrated(start: DiscoveryStart, cfg: DiscoveryConfig,
                        null: NullSettings | None = None, actuation: str = "held",
                        executor: Executor | None = None,
                        inertia_bounds: tuple[Array, Array] | None = None) -> DiscoveryOutcome:
    """Effect discovery (``pinquad.discovery.discover``) from ``start`` with its selection
    calibrated against the null (``pinquad.discovery.null``; default ``NullSettings()``):
    an effect whose evidence does not beat the shadow flights of the base fit is dropped
    from the candidates and the selection reruns without it, until every selected effect
    has beaten the null; only then is the final selection refitted (``refit_selection``).
    actuation: the log's (``LogMeta.actuation``), how the shadow flights are logged.
    executor: worker processes that score the shadow flights and, beside them, refit the
    selection in advance (used when the null keeps it; otherwise the refit is redone on
    the final selection); None: everything here, in turn. inertia_bounds: the vehicle's
    physically possible inertia diagonal (lo, hi) [kg m^2], into which the null clips an
    implausible base fit (``null.plausible_base_fit``), and from which the selection's fits
    and the refit then start. A numerical failure is reported in the outcome, not raised.
    The outcome carries where the log shows the floor (``Observations.floor``), from
    which the ground-effect law measured the height."""
    null = NullSettings() if null is None else null
    calibrations: list[NullCalibration] = []
    obs, theta, post = start.obs, start.theta, start.posterior
    plausible = plausible_base_fit(theta, inertia_bounds)
    start_inertia = None if plausible is theta else np.diag(plausible.inertia)

    def refit_from(sel: Selection) -> Theta:
        # an implausible base fit is no start for the refit's EM either (flightgen 500 Hz
        # flight 3007: from 4e77 kg m^2 the refit kept it and fitted a CoM offset of
        # 1e-106 m); with nothing selected the base fit itself is the answer
        return plausible if sel.selected else theta

    heights = transition_heights(obs, post.mean)
    unphysical: list[dict] = []
    try:
        while True:  # until every selected effect's fit is inside its physical domain
            found = _select_and_refit(obs, theta, post, cfg, null, actuation, executor,
                                      inertia_bounds, start_inertia, calibrations, refit_from)
            bad = outside_domain(found, heights, obs.ground_radius)
            if not bad:
                break
            unphysical += [unexplained_residual(found, e, why) for e, why in bad.items()]
            cfg = replace(cfg, candidates=tuple(c for c in cfg.candidates if c not in bad))
    except (np.linalg.LinAlgError, FloatingPointError, ValueError) as exc:
        return DiscoveryOutcome(None, f"discovery failed numerically: {exc}", floor=obs.floor)
    return DiscoveryOutcome(found, null=combine(calibrations) if calibrations else None,
                            unphysical=tuple(unphysical), floor=obs.floor)


def _select_and_refit(obs: Observations, theta: Theta, post: Posterior, cfg: DiscoveryConfig,
                      null: NullSettings, actuation: str, executor: Executor | None,
                      inertia_bounds: tuple[Array, Array] | None, start_inertia: Array | None,
                      calibrations: list[NullCalibration], refit_from) -> DiscoveryResult:
    """``discover_calibrated``'s selection against the null and its refit (calibrations
    appended to ``calibrations``; effects they rejected stay out)."""
    rejected = {e for c in calibrations for e in c.rejected}
    cfg = replace(cfg, candidates=tuple(c for c in cfg.candidates if c not in rejected))
    sel = select_effects(obs, theta, post, cfg, start_inertia)
    ahead: tuple[Selection, Future] | None = None
    while sel.selected and null.replicates:
        done = {e for c in calibrations for e in c.observed}
        fresh = [e for e in sel.selected if e not in done]
        if not fresh:
            break
        if executor is not None:
            ahead = (sel, executor.submit(refit_selection, obs, refit_from(sel), post,
                                          sel, None, cfg))
        gains = first_round_gains(sel)
        cal = calibrate(obs, theta, post, {e: gains[e] for e in fresh}, cfg, null,
                        actuation, executor, inertia_bounds)
        calibrations.append(cal)
        if not cal.rejected:
            break
        rejected = {e for c in calibrations for e in c.rejected}
        cfg = replace(cfg, candidates=tuple(c for c in cfg.candidates if c not in rejected))
        sel = select_effects(obs, theta, post, cfg, start_inertia)
    if ahead is not None and ahead[0] is sel:
        return ahead[1].result()
    return refit_selection(obs, refit_from(sel), post, sel, None, cfg)
