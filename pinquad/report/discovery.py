"""Effect discovery's figures and report text (``pinquad.discovery`` returns the data).

``draw_discovery_figures`` draws one figure per selected effect from
``DiscoveryResult.evidence``; ``discovery_markdown`` is the ``report.md`` section of a
``DiscoveryResult.to_report()`` section.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from pinquad.discovery.result import ATT_AXES, AXES, GYRO_AXES, DiscoveryResult

FIGURE_DPI = 110


def draw_discovery_figures(result: DiscoveryResult, out_dir: str | Path) -> DiscoveryResult:
    """Draw ``out_dir``/discovery_<effect>.png for each selected effect (two panels: the
    held-out residual of its main rows against its explaining feature before and after
    the refit, from ``result.evidence``) and return ``result`` with ``figures`` set to
    their paths. Nothing is written (and ``out_dir`` not created) when nothing was
    selected."""
    paths = []
    if result.evidence:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
    for ev in result.evidence:
        # the object-oriented API (no pyplot): no global backend or figure registry
        fig = Figure(figsize=(9, 3.6))
        axes = fig.subplots(1, 2, sharey=True)
        for ax, panel in zip(axes, (ev.before, ev.after), strict=True):
            for s in panel.series:
                ax.plot(s.x, s.y, ".", ms=1, label=s.label)
            ax.set_xlabel(panel.x_label)
            ax.set_ylabel(panel.y_label)
            ax.set_title(panel.title)
            ax.legend(markerscale=8, fontsize=7)
        fig.suptitle(f"{ev.effect}: held-out residuals")
        fig.tight_layout()
        path = out / discovery_figure_name(ev.effect)
        fig.savefig(path, dpi=FIGURE_DPI)
        paths.append(str(path))
    return replace(result, figures=tuple(paths))


def discovery_figure_name(effect: str) -> str:
    """The file name of ``effect``'s figure in the run's ``figures/`` (``draw_discovery_figures``)."""
    return f"discovery_{effect}.png"


_AXIS_UNITS = {**{a: "N" for a in AXES[:3]}, **{a: "N m" for a in AXES[3:]},
               **{a: "rad/s" for a in GYRO_AXES + ATT_AXES}}


def discovery_markdown(section: dict) -> str:
    """The ``report.md`` text of a ``DiscoveryResult.to_report()`` section: each selected
    effect with its evidence and coefficients (value +- standard error), the held-out
    residual RMS per axis before/after (and the change in %), the candidate tests and
    the figures (paths as stored in the section, relative to the run directory)."""
    lines = ["## Effect discovery", ""]
    if "error" in section:
        return "\n".join([*lines, f"Not completed: {section['error']}", ""])
    sel = section.get("selected", [])
    if not sel:
        lines.append("No significant unmodelled effect: no candidate passed the held-out test.")
    for s in sel:
        ev = s["evidence"]
        lines.append(f"### {s['effect']}")
        lines.append("")
        lines.append(f"Evidence (round {ev['round']}): held-out SSE on {', '.join(ev['rows'])} "
                     f"falls by {100 * ev['heldout_gain']:.1f} %; held-out log-likelihood "
                     f"+{ev['d_loglik_heldout']:.1f} nats; training BIC margin "
                     f"{ev['d_bic_train']:.1f}.")
        lines.append("")
        lines.append("| coefficient | value | std. error | unit |")
        lines.append("|---|---|---|---|")
        for n, v in s["coefficients"].items():
            lines.append(f"| {n} | {v:.4g} | {s['stderr'][n]:.2g} | {s['units'][n]} |")
        lines.append("")
    before, after = section.get("residual_rms_before", {}), section.get("residual_rms_after", {})
    if before:
        lines += ["### Held-out residual RMS per axis", "",
                  "| axis | before | after | change | unit |", "|---|---|---|---|---|"]
        for a, b in before.items():
            x = after.get(a, float("nan"))
            ch = 100.0 * (x / b - 1.0) if b and np.isfinite(b) and np.isfinite(x) else float("nan")
            lines.append(f"| {a} | {b:.3g} | {x:.3g} | {ch:+.0f} % | {_AXIS_UNITS.get(a, '')} |")
        lines.append("")
    lines += [f"Validation: {section.get('validation', '')}", ""]
    cands = section.get("candidates", [])
    if cands:
        lines += ["### Candidate tests", "", "| round | effect | held-out gain | d loglik (held out) "
                  "| BIC margin | selected |", "|---|---|---|---|---|---|"]
        for c in cands:
            lines.append(f"| {c['round']} | {c['effect']} | {c['heldout_gain']:+.3f} | "
                         f"{c['d_loglik_heldout']:+.1f} | {c['d_bic_train']:+.1f} | "
                         f"{'yes' if c['selected'] else ''} |")
        lines.append("")
    refit = section.get("refit")
    if refit and sel:
        inertia = np.diag(np.asarray(refit["inertia"])) * 1e6
        lines += [f"Refit with the effects: mass {refit['mass'] * 1e3:.2f} g, inertia diagonal "
                  f"({', '.join(f'{v:.2f}' for v in inertia)}) 1e-6 kg m^2.", ""]
    for f in section.get("figures", []):
        lines += [f"![{Path(f).stem}]({f})", ""]
    return "\n".join(lines)
