"""The pipeline's discover step: effect discovery on a log's reported run
(``run_discovery``: the guarded step every caller takes) and on a measured flight's base
fit for the real-vehicle table (``measured_effects``).

The guard: discovery does not run on a base fit that did not converge, and effects read
from a base fit outside the vehicle's physical range are kept only when they bring the
refit inside it (or, with the mass sound, only the force rows' effects are looked for).
"""

from __future__ import annotations

from concurrent.futures import Executor
from dataclasses import replace

import numpy as np

from estimators.protocol import Posterior
from pinquad.discovery.calibrated import (
    DiscoveryOutcome,
    discover_calibrated,
    discovery_config,
    discovery_start,
    start_from,
)
from pinquad.discovery.domain import FORCE_EFFECTS
from pinquad.discovery.null import NullSettings, first_round_gains
from pinquad.identification.identify import unconverged
from pinquad.identification.search_range import outside_range
from pinquad.models.ssm import Observations, Theta
from pinquad.pipeline.identify import LogResult


def run_discovery(result: LogResult, null: NullSettings | None = None,
                  executor: Executor | None = None) -> DiscoveryOutcome:
    """Effect discovery on the reported run (``discover_calibrated``) with the settings
    for the log's kind (``DISCOVERY_SETTINGS``); default ``NullSettings()``; executor
    (``core.execution.worker_pool``): where the null calibration's shadow flights are scored and the
    refit runs beside them (None: all in this process; the answer is the same)."""
    try:
        start = discovery_start(result.runs[0])
    except ValueError as exc:
        return DiscoveryOutcome(None, str(exc))
    vrange = result.plausible
    base = result.runs[0]
    if unconverged(base) is not None:
        return DiscoveryOutcome(None, not_run=unconverged(base))
    actuation = result.actuation
    bounds = None if vrange is None else (vrange.inertia_lo, vrange.inertia_hi)
    cfg = replace(discovery_config(result.kind, actuation), search=result.search)
    outcome = discover_calibrated(start, cfg, null, actuation, executor, bounds)
    # a base fit outside the physical set is kept for discovery only when a selected
    # effect brings the refit inside it (a missing effect can push the base fit out);
    # else, with the mass sound, only the effects of the force rows, which rest on it
    values = np.r_[base.mass, np.diag(base.inertia)]
    odd = outside_range(values, result.search, vrange)
    found = outcome.result
    if odd is None or found is None:
        return outcome
    still = (outside_range(np.r_[found.mass, np.diag(found.inertia)], result.search, vrange)
             if found.selected else odd)
    if still is None:
        return outcome
    if outside_range(values, result.search, vrange, ("mass",)) is None:
        cfg = replace(cfg, candidates=tuple(c for c in cfg.candidates if c in FORCE_EFFECTS))
        forces = discover_calibrated(start, cfg, null, actuation, executor, bounds)
        kept = forces.result
        if kept is None or outside_range(np.r_[kept.mass, np.diag(kept.inertia)],
                                         result.search, vrange, ("mass",)) is None:
            return replace(forces, note=(
                f"the base fit's {odd}: only effects on the force rows "
                f"({', '.join(FORCE_EFFECTS)}), which rest on the mass, were looked for"))
    return DiscoveryOutcome(None, not_run=(
        f"the base fit's {odd}, and "
        + (f"the refit with {', '.join(found.selected)} still has {still}"
           if found.selected else "no effect explains why")
        + ": the log does not determine the fit, and effects read from its residual "
        "would not be there"))


def measured_effects(obs: Observations, theta: Theta, posterior: Posterior,
                     null: NullSettings | None = None) -> dict:
    """Effect discovery with its null calibration on a measured flight's base fit (its
    nuisance moment moved into the torques, as ``discovery_start``), summarised for the
    real-vehicle table: ``selected`` [{effect, heldout_gain, null_gain_max, p_value}],
    ``rejected`` (effects the null explained), ``replicates``, ``seed``, ``error``."""
    outcome = discover_calibrated(start_from(obs, theta, posterior), discovery_config("sdlog"),
                                  null)
    cal = outcome.null
    out: dict = {"selected": [], "rejected": [] if cal is None else list(cal.rejected),
                 "replicates": 0 if cal is None else cal.replicates,
                 "seed": None if cal is None else cal.seed, "error": outcome.error}
    if outcome.result is None:
        return out
    gains = first_round_gains(outcome.result)
    for e in outcome.result.selected:
        entry = {"effect": e, "heldout_gain": gains.get(e), "null_gain_max": None,
                 "p_value": None}
        if cal is not None and e in cal.null_gains:
            entry["null_gain_max"] = float(np.max(cal.null_gains[e]))
            entry["p_value"] = cal.p_value[e]
        out["selected"].append(entry)
    return out
