"""The headline of a recorded log: the estimate under the final model (after discovery's
refit when effects were selected, else the base fit), the base fit beside it, and a
verdict (``pinquad.identification.verdict``) for each of them and for every run."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from pinquad.discovery.calibrated import DiscoveryOutcome, discovery_config, discovery_start
from pinquad.discovery.refit import corrected_observations, model_factory
from pinquad.discovery.result import DiscoveryResult
from pinquad.estep.fast_smoother import loglik_quad
from pinquad.identification.budget import ErrorBudget, calibration_of, error_budget
from pinquad.identification.edges import collapsed_errors
from pinquad.identification.fisher import (
    STDERR_UNAVAILABLE,
    observed_information,
    standard_errors,
)
from pinquad.identification.identify import Identification, unconverged
from pinquad.identification.mass_balance import balance_mass
from pinquad.identification.reference import log_reference
from pinquad.identification.search_range import at_bound
from pinquad.identification.verdict import EstimateVerdict, VerdictEvidence, judge
from pinquad.identification.verdict_evidence import data_evidence
from pinquad.models.full import FullQuadSSM
from pinquad.pipeline.identify import LogResult

Array = NDArray[np.float64]


@dataclass(frozen=True)
class VehicleEstimate:
    """One estimate of the vehicle, whose parameters are each a ``verdict.Estimate``
    (value, total error, its parts, verdict, reasons: ``verdict.parameters``): mass [kg],
    inertia (3, 3) [kg m^2], com (3,) [m] or None, stderr (4,) of [m, I_xx, I_yy, I_zz]
    (NaN: not computed; the budget's total), stderr_note: how it was computed, model: the
    model it was fitted under, in words; verdict; budget: stderr by named part (None: no
    budget)."""

    mass: float
    inertia: Array
    com: Array | None
    stderr: Array
    stderr_note: str
    model: str
    verdict: EstimateVerdict
    budget: ErrorBudget | None = None

    def to_report(self) -> dict:
        """report.json's estimate layout (``estimates``, plus the verdict)."""
        return {"mass": self.mass, "inertia": np.asarray(self.inertia).tolist(),
                "com": None if self.com is None else np.asarray(self.com).tolist(),
                "stderr": {"mass": self.stderr[0], "inertia_diag": self.stderr[1:].tolist()},
                "stderr_parts": None if self.budget is None else self.budget.to_report(),
                "stderr_note": self.stderr_note, "model": self.model,
                "verdict": self.verdict.to_report()}


@dataclass(frozen=True)
class Headline:
    """What a log's report leads with: final (the estimate under the final model), base
    (the base fit, the reported run) and one verdict per run (``LogResult.runs`` order).
    ``final is base`` when no effect was selected or discovery did not run."""

    final: VehicleEstimate
    base: VehicleEstimate
    run_verdicts: tuple[EstimateVerdict, ...]

    @property
    def refitted(self) -> bool:
        return self.final is not self.base


def _band(run: Identification) -> tuple[float, float] | None:
    """The measured-flight M-step reads the inertia from its torque band only."""
    return None if run.measured is None else tuple(run.measured.band)


def run_budget(result: LogResult, run: Identification, values: Array | None = None,
               statistical: Array | None = None) -> ErrorBudget:
    """The error budget (``identification.budget``) of a run of the log, or of an estimate
    built on it (``values`` (4,) with its ``statistical`` errors; default the run's own):
    a measured flight's statistical part is its information/jackknife error, its thrust
    part kf's; a log with thrust and torque columns takes its sidecar's, its vehicle
    file's or the default calibration; the reported run carries the input reading."""
    values = np.r_[run.mass, np.diag(run.inertia)] if values is None else values
    ident = run.measured
    if ident is not None:
        cal = calibration_of(result.log.meta, (ident.kf.rel_se, ident.yaw_rel))
        stat = ident.se_stat if statistical is None else statistical
        return error_budget(values, stat, cal, repair_rel=ident.repair_rel)
    alt = result.input_alternative if run is result.runs[0] else None
    stat = np.asarray(run.stderr, dtype=float) if statistical is None else statistical
    return error_budget(values, stat, calibration_of(result.log.meta), alt)


def with_budget(evidence: VerdictEvidence, budget: ErrorBudget,
                result: LogResult) -> VerdictEvidence:
    """The evidence with what the estimate's error budget and the log's vehicle add: the
    errors without the input reading's part (the input check), the mass's error without
    what the model-free balance shares, the vehicle file's reference."""
    return replace(evidence, input_free_stderr=budget.total_without("input_reading"),
                   balance_stderr=float(budget.unshared_with_thrust()[0]),
                   reference=log_reference(result.log.meta))


def error_failures(run: Identification) -> tuple[tuple[str, str], ...]:
    """(name, reason) of the run's parameters whose statistical error collapsed
    (``edges.collapsed_errors``): a measured flight's block jackknife against its
    observed information, else the information's error alone."""
    values = np.r_[run.mass, np.diag(run.inertia)]
    if run.measured is not None:
        return collapsed_errors(values, {"observed information": run.measured.se_info,
                                         "block jackknife": run.measured.se_jack})
    return collapsed_errors(values, {"observed information": run.stderr})


def fit_evidence(result: LogResult, run: Identification) -> dict:
    """What the fit itself says against trusting a run (``VerdictEvidence`` fields):
    EM did not converge (unless its iterates have settled: the rest of the way,
    ``em.remaining_move``, is under ``SETTLED_SHARE`` of every statistical standard
    error, as when only a noise variance still creeps), or parameters ended on the edge
    of the range EM searched, or its error estimates collapsed (``edges``: a measured
    flight's block jackknife against its observed information, else the information's
    error alone)."""
    values = np.r_[run.mass, np.diag(run.inertia)]
    out: dict = {"error_failures": error_failures(run)}
    if unconverged(run) is not None:
        why = f" ({run.failure})" if run.failure else ""
        out["not_converged"] = (f"EM did not converge in {run.e_steps or run.iterations} "
                                f"E-steps{why}: the estimate is not the likelihood's maximum")
    if result.search is not None and run.mstep != "full":
        out["at_bound"] = tuple(at_bound(values, result.search))
        out["bound_source"] = result.search.source
    return out


def run_verdict(result: LogResult, run: Identification) -> EstimateVerdict:
    """The verdict of one run of a log (its own posterior and observations; a run that kept
    none is judged on its values and standard errors alone)."""
    try:
        start = discovery_start(run)
    except ValueError:
        ev = VerdictEvidence()
    else:
        theta = replace(start.theta, inertia=np.asarray(run.inertia))
        model = None if run.full is None else FullQuadSSM(start.obs, theta)
        ev = data_evidence(start.obs, theta, start.posterior.mean, _band(run), model,
                           result.actuation)
        ev = replace(ev, model_free_mass=balance_mass(start.obs, start.posterior.mean,
                                                       start.theta.gravity))
    if run is result.runs[0]:
        ev = replace(ev, input_alternative=result.input_alternative)
    ev = replace(ev, **fit_evidence(result, run))
    products = None
    if run.full is not None:
        s = np.asarray(run.full.stderr_inertia)
        products = np.array([s[0, 1], s[0, 2], s[1, 2]])
    budget = run_budget(result, run)
    ev = with_budget(ev, budget, result)
    return judge(run.mass, run.inertia, budget.total, ev,
                 result.plausible, products, missing_stderr=run.stderr_problem,
                 parts=budget.parts)


def _base(result: LogResult, verdict: EstimateVerdict) -> VehicleEstimate:
    run = result.runs[0]
    note = ("total of stderr_parts: statistical (observed information or block jackknife) "
            "with what the estimate assumed" if run.measured is not None
            else "total of stderr_parts: statistical (observed information of the EKF "
            "likelihood) with what the estimate assumed")
    budget = run_budget(result, run)
    return VehicleEstimate(run.mass, np.asarray(run.inertia), run.com, budget.total,
                    note, f"base rigid-body model ({run.mstep} M-step, sensor {run.sensor})",
                    verdict, budget)


def _final(result: LogResult, found: DiscoveryResult, base: VehicleEstimate
           ) -> VehicleEstimate:
    run = result.runs[0]
    start = discovery_start(run)
    theta = replace(found.theta, mass=float(found.mass), inertia=np.asarray(found.inertia))
    obs = corrected_observations(start.obs, found.posterior.mean, found.coefficients)
    model = model_factory(found.coefficients)(obs, theta)
    ev = replace(data_evidence(obs, theta, found.posterior.mean, _band(run), model,
                               result.actuation),
                 input_alternative=result.input_alternative)
    if result.search is not None:
        ev = replace(ev, at_bound=tuple(at_bound(np.r_[found.mass, np.diag(found.inertia)],
                                                 result.search)),
                     bound_source=result.search.source)
    missing = run.stderr_problem
    if discovery_config(result.kind).refit_em:
        statistical = standard_errors(observed_information(obs, theta, loglik_quad))
        failures = collapsed_errors(
            np.r_[found.mass, np.diag(found.inertia)],
            {"refit's observed information": statistical},
            {"base fit's statistical error": None if base.budget is None
             else base.budget.parts["statistical"]})
        missing = STDERR_UNAVAILABLE
        note = ("observed information of the EKF likelihood on the observations with the "
                "selected effects' thrust and torque folded in (body x/y forces of drag or "
                "wind are not in this likelihood)")
    else:  # the base fit's statistical errors (a measured flight's, when it is one)
        assert base.budget is not None
        statistical = (run.measured.se_stat if run.measured is not None
                       else base.budget.parts["statistical"])
        failures = error_failures(run)
        note = ("the base fit's (discovery keeps the base inertia and refits the mass on the "
                "base posterior's force rows)")
    budget = run_budget(result, run, np.r_[found.mass, np.diag(found.inertia)], statistical)
    stderr = budget.total
    ev = replace(with_budget(ev, budget, result), error_failures=failures)
    verdict = judge(found.mass, found.inertia, stderr, ev, result.plausible,
                    missing_stderr=missing, parts=budget.parts)
    return VehicleEstimate(float(found.mass), np.asarray(found.inertia), None, np.asarray(stderr),
                           note,
                    f"base model plus {', '.join(found.selected)} (discovery's refit)", verdict,
                    budget)


def headline(result: LogResult, outcome: DiscoveryOutcome | None) -> Headline:
    """The headline of a log's identification (module docstring): the final model is
    discovery's refit when ``outcome`` selected effects, else the base fit."""
    verdicts = tuple(run_verdict(result, r) for r in result.runs)
    base = _base(result, verdicts[0])
    found = None if outcome is None else outcome.result
    if found is None or not found.selected:
        return Headline(base, base, verdicts)
    return Headline(_final(result, found, base), base, verdicts)
