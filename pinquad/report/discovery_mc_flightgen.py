"""The tables of the flightgen discovery Monte Carlo (``python -m pinquad.discovery
--generator flightgen``; rows from ``pinquad.experiments.discovery_mc_flightgen.summarize``)."""

from __future__ import annotations

import math


def _pct(v: float) -> str:
    return "-" if not math.isfinite(v) else f"{100.0 * v:.1f} %"


def flightgen_mc_markdown(rows: list[dict]) -> str:
    """Markdown: one row per (log rate, condition) with the counts against the targets,
    then the base EM's and the reported estimates' RMS relative errors."""
    head = ("| log rate | condition | n | named | exact set | nothing selected | "
            "coef within 10 % | coef within 2 se | rms of (c - c0) / se | coef err median / max | "
            "held-out gain median | extra selected | rejected by the null (flights: effects) |")
    lines = [head, "|" + "---|" * 13]
    for r in rows:
        if "named" not in r:  # no effect injected: clean or floor-strike flights
            named = exact = within = covered = z_rms = err = gain = ""
        else:
            named, exact = f"{r['named']}/{r['n']}", f"{r['exact']}/{r['n']}"
            within = f"{r['coef_within_10pct']}/{r['n']}"
            if r.get("noise_only_n"):
                within += (f" (the thrust noise alone: {r['noise_only_within_10pct']}"
                           f"/{r['noise_only_n']})")
            # runs made before the standard errors were recorded leave it blank
            covered = (f"{r['coef_within_2se']}/{r['coef_with_stderr']}"
                       if r.get("coef_with_stderr") else "")
            z_rms = ", ".join(f"{z:.2g}" for z in r.get("coef_z_rms", []))
            err = f"{_pct(r['coef_err_median'])} / {_pct(r['coef_err_max'])}"
            gain = _pct(r["gain_median"])
        extra = ", ".join(r["extra_selected"]) or "-"
        rejected = (f"{r.get('null_rejected', 0)}/{r['n']}: "
                    + (", ".join(r.get("null_rejected_effects", [])) or "-"))
        lines.append(f"| {r['log_rate']} Hz | {r['condition']} | {r['n']} | {named} | {exact} | "
                     f"{r['nothing_selected']}/{r['n']} | {within} | {covered} | {z_rms} | {err} | {gain} | "
                     f"{extra} | "
                     f"{rejected} |")
    lines += ["", "RMS relative error over the seeds, base EM -> reported (refit when an "
              "effect is selected):", "",
              "| log rate | condition | mass | I_xx | I_yy | I_zz |", "|---|---|---|---|---|---|"]
    for r in rows:
        cells = [f"{_pct(r['base_rms_rel_err'][p])} -> {_pct(r['final_rms_rel_err'][p])}"
                 for p in ("mass", "I_xx", "I_yy", "I_zz")]
        lines.append(f"| {r['log_rate']} Hz | {r['condition']} | " + " | ".join(cells) + " |")
    floor = [r for r in rows if "contact" in r]
    if floor:
        lines += ["", "Floor strikes without a contact column (take-off, two strikes, landing): "
                  "transitions touching the floor in the truth, found from the data, missed, "
                  "found off the floor (summed over the flights):", "",
                  "| log rate | n | nothing selected | selected | true | found | missed | "
                  "found off the floor | flights with every contact found | "
                  "excluded near the Euler singularity (flights: transitions) |",
                  "|---|---|---|---|---|---|---|---|---|---|"]
        for r in floor:
            c = r["contact"]
            lines.append(f"| {r['log_rate']} Hz | {r['n']} | {r['nothing_selected']}/{r['n']} | "
                         f"{', '.join(r['extra_selected']) or '-'} | {c['true']} | {c['found']} | "
                         f"{c['missed']} | {c['off']} | {r['contact_all_found']}/{r['n']} | "
                         f"{r.get('singular_flights', 0)}: {r.get('singular_excluded', 0)} |")
    judged = [r for r in rows if r.get("judged")]
    if judged:
        lines += ["", "Verdicts of the reported estimates: parameters more than 10 % from the "
                  "truth, called trusted (a confident wrong answer) / called not trusted:", "",
                  "| log rate | condition | judged | mass | I_xx | I_yy | I_zz |",
                  "|---|---|---|---|---|---|---|"]
        for r in judged:
            cells = [f"{r['trusted_but_off'][p]} / {r['off_flagged'][p]}"
                     for p in ("mass", "I_xx", "I_yy", "I_zz")]
            lines.append(f"| {r['log_rate']} Hz | {r['condition']} | {r['judged']} | "
                         + " | ".join(cells) + " |")
    return "\n".join(lines)
