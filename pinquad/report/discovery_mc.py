"""The discovery Monte Carlo's result tables (``python -m pinquad.discovery``), from the
summary ``pinquad.experiments.discovery_mc.summarize`` computes."""

from __future__ import annotations

import numpy as np

from pinquad.experiments.discovery_mc import AFFECTED_AXES, CONDITIONS, PARAMS


def discovery_mc_markdown(summary: dict) -> str:
    """The result tables of a ``discovery_mc.summarize`` summary (one row per condition),
    with the paired, pooled, drop and floor lines under them."""
    cr = summary["clean_rms_rel_err"]
    lines = ["| condition | n | named (all) | exact set | coef within 10 % | coef err median / max "
             "| refit within clean acc. | refit within clean acc. of its clean twin "
             "| affected-axis median RMS drop | extra selected |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for cond, r in summary["conditions"].items():
        if cond == "none":
            lines.append(f"| none | {r['n']} | nothing selected {r['nothing_selected']}/{r['n']} | "
                         f"| | | {r.get('within_clean_accuracy', '')}/{r['n']} | | | "
                         f"{', '.join(r['spurious']) or '-'} |")
            continue
        effs = CONDITIONS[cond]
        within = "; ".join(f"{e} {r[f'{e}_coef_within_10pct']}/{r['n']}" for e in effs)
        errs = "; ".join(f"{100 * r[f'{e}_coef_rel_err_median']:.1f} / "
                         f"{100 * r[f'{e}_coef_rel_err_max']:.1f} %" for e in effs)
        drops = "; ".join(", ".join(f"{a} {100 * v:.0f} %" for a, v in r[f"{e}_median_drop"].items())
                          for e in effs)
        lines.append(f"| {cond} | {r['n']} | {r['all_named']}/{r['n']} | {r['exact']}/{r['n']} | "
                     f"{within} | {errs} | {r.get('within_clean_accuracy', '')}/{r['n']} | "
                     f"{_twin_count(r)} | {drops} | "
                     f"{', '.join(r['extra_selected']) or '-'} |")
    lines += ["", "RMS relative error of mass and inertia over the seeds, base EM -> after the refit "
              "(the none row is the clean-data accuracy):", "",
              "| condition | mass | I_xx | I_yy | I_zz |", "|---|---|---|---|---|"]
    for cond, r in summary["conditions"].items():
        lines.append(f"| {cond} | " + " | ".join(
            f"{100 * r['base_rms_rel_err'][k]:.2f} -> {100 * r['refit_rms_rel_err'][k]:.2f} %"
            for k in PARAMS) + " |")
    paired = [(c, r) for c, r in summary["conditions"].items() if "twin_rms_rel_err" in r]
    if paired:
        lines += ["", "Paired with the clean twins (the same seeds flown without the effect, base "
                  "EM): RMS relative error of the twins -> of the refit on the effect's flights:",
                  "", "| condition | twins | mass | I_xx | I_yy | I_zz |", "|---|---|---|---|---|---|"]
        for cond, r in paired:
            lines.append(f"| {cond} | {r['twin_n']} | " + " | ".join(
                f"{100 * r['twin_rms_rel_err'][k]:.2f} -> {100 * r['refit_rms_rel_err_paired'][k]:.2f} %"
                for k in PARAMS) + " |")
    pr = summary.get("clean_pooled_rms_rel_err")
    if pr and summary.get("clean_pooled_n", 0) > len(summary["conditions"].get("none", {}).get(
            "seeds", [])):
        rows = "; ".join(f"{c} {r['within_pooled_clean_accuracy']}/{r['n']}"
                         for c, r in summary["conditions"].items()
                         if c != "none" and "within_pooled_clean_accuracy" in r)
        lines += ["", f"Clean-data accuracy from all {summary['clean_pooled_n']} clean flights of "
                  "the run (the no-effect seeds and every effect seed's clean twin, identified "
                  "alike): RMS relative error " + ", ".join(f"{k} {100 * v:.2f} %" for k, v in
                                                            pr.items())
                  + f"; clean flights with every parameter within 2x that: "
                  f"{summary['clean_pooled_within']}/{summary['clean_pooled_n']}; refits: {rows}."]
    counts = []
    for cond, r in summary["conditions"].items():
        for e in CONDITIONS.get(cond, ()):
            axes = [a for a in AFFECTED_AXES[e] if f"{e}_drop50_{a}" in r]
            if axes:
                counts.append(f"{cond} ({e}): " + ", ".join(
                    f"{a} {r[f'{e}_drop50_{a}']}/{r['n']}"
                    + (f" ({r[f'{e}_reachable50_{a}']})" if f"{e}_reachable50_{a}" in r else "")
                    for a in axes))
    if counts:
        lines += ["", "Seeds whose held-out RMS drops by >= 50 % on each affected axis (in "
                  "brackets: seeds where the effect at least doubles the clean twin's RMS, so "
                  "that a refit leaving exactly the twin's noise floor would drop by 50 %): "
                  + "; ".join(counts) + "."]
    floors = []
    for cond, r in summary["conditions"].items():
        for e in CONDITIONS.get(cond, ()):
            fl = r.get(f"{e}_median_after_over_twin", {})
            ex = r.get(f"{e}_median_before_over_twin", {})
            if fl and any(np.isfinite(v) for v in fl.values()):
                floors.append(f"{cond} ({e}): " + ", ".join(
                    f"{a} {ex.get(a, float('nan')):.2f} -> {v:.2f}" for a, v in fl.items()))
    if floors:
        lines += ["", "Held-out RMS before -> after the refit, each over the clean twin's under "
                  "the base model (the floor the noise leaves on the same blocks), median over "
                  "the seeds (before near 1: the effect barely shows on that axis; after 1: "
                  "nothing of it left): " + "; ".join(floors) + "."]
    lines.append("")
    lines.append("Clean-data accuracy (RMS relative error, no effect): "
                 + ", ".join(f"{k} {100 * v:.2f} %" for k, v in cr.items())
                 + "; 'within' = every parameter within 2x that; 'of its clean twin': for "
                 "every parameter |refit error| <= |twin's error| + 2x that (no worse than the "
                 "same seed flown without the effect, by more than twice the clean accuracy).")
    return "\n".join(lines)


def _twin_count(row: dict) -> str:
    return f"{row['within_clean_of_twin']}/{row['twin_n']}" if "within_clean_of_twin" in row else ""
