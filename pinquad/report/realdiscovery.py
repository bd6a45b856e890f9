"""The table of effect discovery on the measured flights (``python -m pinquad.realdiscovery``,
``pinquad.experiments.realdiscovery``)."""

from __future__ import annotations

import numpy as np

from pinquad.discovery.library import SPECS
from pinquad.experiments.realdiscovery import NEAR_FLOOR_M


def realdiscovery_markdown(results: dict) -> str:
    """Markdown of ``run_split``'s entries by split name: per split the effects,
    coefficients and the test flights' force residual RMS before/after [mN], then the
    split's own effect fitted alone."""
    lines = ["| split | train (lowest height, top speed) | named per flight (own discovery) | "
             "pooled effect: coefficients ± leave-one-flight-out SE | test flight | "
             "force_x before -> after [mN] | force_y | force_z |", "|---|---|---|---|---|---|---|---|"]
    for name, r in results.items():
        named = "; ".join(f"{k}: {', '.join(v) or '-'}" for k, v in r["named_by_flight"].items())
        co = "; ".join(
            f"{e}: " + ", ".join(f"{n} {v:.4g} ± {s:.2g}" for n, v, s in
                                 zip(SPECS[e].coefficient_names, r["coefficients"][e],
                                     r["stderr_leave_one_flight_out"][e], strict=True))
            for e in r["pooled_effects"]) or "none"
        for i, (t, rms) in enumerate(r["test_rms"].items()):
            b, a = rms["before"], rms["after"]
            cells = " | ".join(f"{1e3 * b[x]:.2f} -> {1e3 * a[x]:.2f} ({100 * (a[x] / b[x] - 1):+.0f} %)"
                               for x in ("force_x", "force_y", "force_z"))
            tr = ", ".join(f"{n} ({r['flights'][n][0]:.2f} m, {r['flights'][n][1]:.1f} m/s)"
                           for n in r["train"])
            lead = (f"| {name} | {tr} | {named} | {co} |" if i == 0
                    else "| | | | |")
            lines.append(f"{lead} {t} ({r['flights'][t][0]:.2f} m, {r['flights'][t][1]:.1f} m/s) | "
                         f"{cells} |")
    lines += ["", "The split's own effect fitted alone on the training flights, test flights' force "
              "residual RMS before -> after:", ""]
    for name, r in results.items():
        tg = r["target"]
        co = ", ".join(f"{n} {v:.4g}" for n, v in zip(SPECS[tg["effect"]].coefficient_names,
                                                       tg["coefficients"], strict=True))
        for t, rms in tg["test_rms"].items():
            b, a = rms["before"], rms["after"]
            words = ", ".join(
                f"{x} {1e3 * b[x]:.2f} -> {1e3 * a[x]:.2f} mN ({100 * (a[x] / b[x] - 1):+.0f} %)"
                for x in ("force_x", "force_y", "force_z"))
            low = tg.get("near_floor", {}).get(t)
            if low is not None and np.isfinite(low["before"]["force_z"]):
                b, a = low["before"], low["after"]
                words += (f"; below {100 * NEAR_FLOOR_M:.0f} cm ({low['seconds']:.1f} s of the "
                          f"flight): force_z {1e3 * b['force_z']:.2f} -> {1e3 * a['force_z']:.2f} mN "
                          f"({100 * (a['force_z'] / b['force_z'] - 1):+.0f} %)")
            lines.append(f"- {name}: {tg['effect']} alone ({co}) on {t}: {words}")
    return "\n".join(lines)
