"""Effect discovery's results as the report and the real-vehicle table show them: the
``discovery`` section of report.json, and the measured flights' effects with their
evidence against the null."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from estimators.protocol import Posterior
from pinquad.discovery.calibrated import DiscoveryOutcome, discover_calibrated, discovery_config, start_from
from pinquad.discovery.null import NullSettings, first_round_gains
from pinquad.models.ssm import Observations, Theta


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


def discovery_section(outcome: DiscoveryOutcome) -> dict:
    """The ``discovery`` section of report.json; figure paths (if drawn) named
    relative to the run directory (``figures/<name>``); ``ground_effect_floor``: where
    the ground-effect law put the floor ({'height' [m], 'source', 'note'}; None when
    discovery did not reach the log)."""
    floor = None if outcome.floor is None else {
        "height": outcome.floor.height, "source": outcome.floor.source,
        "note": outcome.floor.describe()}
    if outcome.result is None:
        return {"selected": [], "residual_rms_before": {}, "residual_rms_after": {},
                "validation": "not run", "error": outcome.error, "not_run": outcome.not_run,
                "note": outcome.note, "unphysical": list(outcome.unphysical),
                "ground_effect_floor": floor}
    section = outcome.result.to_report()
    section["ground_effect_floor"] = floor
    section["unphysical"] = list(outcome.unphysical)
    section["note"] = outcome.note
    section["not_run"] = None
    section["figures"] = [f"figures/{Path(f).name}" for f in section["figures"]]
    if outcome.null is not None:
        section["null_calibration"] = outcome.null.to_report()
        for entry in section["selected"]:
            entry["evidence"]["null_p_value"] = outcome.null.p_value.get(entry["effect"])
    else:
        section["null_calibration"] = {"replicates": 0, "note": (
            "nothing selected: no calibration needed" if not section["selected"]
            else "not calibrated against the null (--null-replicates 0)")}
    return section
