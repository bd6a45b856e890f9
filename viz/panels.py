"""The text panels of a run's view: the header with its legend, the parameter table,
the status line under the playback controls, the effect-discovery outcome with its
figures, the run's figures and its warnings.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import rotation_from_euler
from viz.plots import ESTIMATE_CSS, TRUTH_CSS
from viz.recorded import PARAMS, EstimateRow, Headline
from viz.run import CycleRecord, Discovery, Flight, Run
from viz.scene import COLORMAP

if TYPE_CHECKING:
    import viser

Array = NDArray[np.float64]

MAX_FIGURE_WIDTH = 1400
"""Figures wider than this are subsampled before sending: the panel is narrower."""


def read_png(path: Path) -> NDArray[np.uint8] | None:
    """RGB image of a PNG file, or None if it cannot be read."""
    try:
        # deferred on purpose: imageio comes with viser, the viewer's optional dependency
        import imageio.v3 as iio

        img = np.asarray(iio.imread(path))
    except Exception:  # imageio raises many types for damaged files; skip the figure
        return None
    if img.dtype != np.uint8:
        img = (np.clip(img.astype(float) / (np.iinfo(img.dtype).max if img.dtype.kind in "ui"
                                            else 1.0), 0, 1) * 255).astype(np.uint8)
    if img.ndim == 2:
        img = np.repeat(img[:, :, None], 3, axis=2)
    if img.shape[2] == 4:
        # Composite on white: matplotlib figures may be transparent.
        alpha = img[:, :, 3:4].astype(float) / 255.0
        img = (img[:, :, :3] * alpha + 255.0 * (1.0 - alpha)).astype(np.uint8)
    step = int(math.ceil(img.shape[1] / MAX_FIGURE_WIDTH))
    return np.ascontiguousarray(img[::step, ::step, :3])


def fmt_pct(est: float, truth: float | None) -> str:
    """Relative error of ``est`` against ``truth`` in percent; "-" without a truth."""
    if truth is None or truth == 0:
        return "-"
    return f"{100.0 * (est - truth) / truth:+.2f} %"


def cycle_label(rec: CycleRecord) -> str:
    """The Cycle dropdown's entry of ``rec``: its number, and its seed if known."""
    return f"{rec.cycle}" + ("" if rec.seed is None else f" (seed {rec.seed})")


def vehicle_words(run: Run, scale: float) -> str:
    """What the header says of the vehicle: its name and the drawn size, or, when the
    log named none, that it did not (``Run.vehicle_note``'s first clause)."""
    size = "drawn at its real size" if scale == 1.0 else f"drawn x{scale:.3g} its size"
    if not run.vehicle_named:
        note = run.vehicle_note.split(" (", 1)[0] or "vehicle not named by the log"
        return f"**{note}**" + ("" if scale == 1.0 else f", magnified x{scale:.3g}")
    return f"vehicle `{run.vehicle}` ({size})"


def header_markdown(run: Run, scale: float) -> str:
    """The view's first line: run, kind, vehicle (drawn ``scale`` times its size, or
    that the log named none) and the legend of the paths it has."""
    legend = []
    if any(f.true_pos is not None for f in run.flights):
        legend.append(f"<span style='color:{TRUTH_CSS}'>&#9644;</span> true path")
    if any(f.est_pos is not None for f in run.flights):
        legend.append(f"<span style='color:{ESTIMATE_CSS}'>&#9644;</span> estimated path "
                      "(dashed)")
    if any(f.mocap is not None for f in run.flights):
        legend.append("&#8226; raw motion capture (toggle)")
    return (f"**{run.path.name}** &middot; {run.kind} run &middot; {vehicle_words(run, scale)}"
            "  \n" + " &nbsp; ".join(legend))


def parameter_markdown(rec: CycleRecord) -> str:
    """Table of the final estimates of ``rec`` (g, 1e-6 kg m^2) beside the truth."""
    truth = [rec.true_mass] + ([None] * 3 if rec.true_inertia_diag is None
                               else list(rec.true_inertia_diag))
    known = any(v is not None for v in truth)
    # A recorded flight has no truth: its table is the estimate alone.
    rows = (["| | estimate | truth | error |", "|---|---|---|---|"] if known
            else ["| | estimate of this run |", "|---|---|"])
    ests = [rec.est_mass, *rec.est_inertia_diag]
    for name, unit, k, est, tru in zip(("mass", "Ixx", "Iyy", "Izz"),
                                       ("g", "1e-6 kg m²", "1e-6 kg m²", "1e-6 kg m²"),
                                       (1e3, 1e6, 1e6, 1e6), ests, truth, strict=True):
        tru_txt = "-" if tru is None else f"{tru * k:.4g}"
        rows.append(f"| {name} [{unit}] | {est * k:.4g} | {tru_txt} | {fmt_pct(est, tru)} |"
                    if known else f"| {name} [{unit}] | {est * k:.4g} |")
    n = rec.x.shape[0]
    if rec.e_steps is not None:
        count = f"{rec.e_steps} E-steps ({n} iterates plotted, the first the initial guess)"
    else:
        count = f"{n} {'updates' if rec.x_label not in ('EM iteration', 'EM iterate') else 'iterations'}"
    return (f"Sensor {rec.sensor}, cycle {rec.cycle}, {rec.mstep} M-step, {count}\n\n"
            + "\n".join(rows))


UNITS = (("mass", "g", 1e3, ".3f"), ("Ixx", "1e-6 kg m²", 1e6, ".2f"),
         ("Iyy", "1e-6 kg m²", 1e6, ".2f"), ("Izz", "1e-6 kg m²", 1e6, ".2f"))


def _cell(row: EstimateRow, i: int) -> str:
    _, _, k, fmt = UNITS[i]
    se = row.stderr[i]
    text = f"{row.values[i] * k:{fmt}}" + ("" if not np.isfinite(se) else f" ± {se * k:{fmt}}")
    verdict, reason = row.verdicts.get(PARAMS[i], ("", ""))
    if verdict and verdict != "trusted":
        text += f" **{verdict}**"
    return text


def headline_markdown(h: Headline) -> str:
    """The headline table of a recorded log: the final model's estimate ± standard error
    with each parameter's verdict, the base fit beside it when discovery changed it, the
    reference values when the vehicle has them; then the overall verdict and reasons."""
    cols = ["final model"]
    if h.base is not None:
        cols.append("base fit")
    if h.reference is not None:
        cols.append("reference")
    rows = ["| | " + " | ".join(cols) + " |", "|---|" + "---|" * len(cols)]
    for i, (name, unit, k, fmt) in enumerate(UNITS):
        cells = [_cell(h.final, i)]
        if h.base is not None:
            cells.append(_cell(h.base, i))
        if h.reference is not None:
            cells.append(f"{h.reference[i] * k:{fmt}}")
        rows.append(f"| {name} [{unit}] | " + " | ".join(cells) + " |")
    text = [f"**Headline estimate** (verdict: **{h.final.overall}**)"
            + (f"  \nfinal model: {h.final.model}" if h.final.model else ""), "", *rows]
    text += [f"- {r}" for r in h.final.reasons]
    if h.reference is not None:
        text.append(f"\n_reference: {h.reference_source}_")
    if h.base is not None:
        text.append("\n_base fit: the rigid-body model before discovery's refit_")
    return "\n".join(text)


def residual_legend(column: str, top: float, note: str) -> str:
    """The colour key of the residual-coloured path: its scale from 0 to ``top`` (in mN
    or 1e-6 N m), and how the residual was computed."""
    force = column.startswith("force")
    k, unit = (1e3, "mN") if force else (1e6, "1e-6 N m")
    stops = "".join(f"<span style='color:rgb{tuple(int(v) for v in c)}'>&#9632;</span>"
                    for c in COLORMAP)
    which = "base fit" if column.endswith("before") else "final model"
    return (f"{'force' if force else 'torque'} residual, {which}: 0 {stops} "
            f"&ge; {top * k:.3g} {unit} (grey: no transition used)  \n_{note}_")


def status_markdown(f: Flight, t: float, truth: tuple[Array, Array] | None,
                    est: tuple[Array, Array] | None) -> str:
    """Status line at time ``t`` [s] of ``f``: how far the estimated pose is from the
    true one (mm, degrees) and the position [m]; poses as (position, quaternion wxyz)."""
    i = f.index_at(t)
    text = f"t = {f.t[i]:.2f} s"
    if truth is not None and est is not None:
        dp = 1e3 * float(np.linalg.norm(truth[0] - est[0]))
        r_true = rotation_from_euler(f.true_euler[i])  # type: ignore[index]
        r_est = rotation_from_euler(f.est_euler[i])  # type: ignore[index]
        cos = (np.trace(r_true.T @ r_est) - 1.0) / 2.0
        dang = math.degrees(math.acos(float(np.clip(cos, -1.0, 1.0))))
        text += f" &middot; estimate off by {dp:.1f} mm, {dang:.2f}°"
    pose = truth or est
    if pose is not None:
        p = pose[0]
        text += f"  \nposition ({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) m"
    return text


def discovery_markdown(disc: Discovery) -> str:
    """The effects discovery selected and the residual RMS before and after."""
    lines = []
    if disc.selected:
        lines.append("Selected effects:\n")
        lines += [f"- **{name}**" + (f": {coef}" if coef else "") for name, coef in disc.selected]
    else:
        lines.append("No significant unmodelled effect.")
    before, after = dict(disc.rms_before), dict(disc.rms_after)
    channels = list(dict.fromkeys([*before, *after]))
    if channels:
        lines += ["", "| residual RMS | before | after |", "|---|---|---|"]
        for ch in channels:
            b = f"{before[ch]:.4g}" if ch in before else "-"
            a = f"{after[ch]:.4g}" if ch in after else "-"
            lines.append(f"| {ch} | {b} | {a} |")
    if disc.validation:
        lines += ["", f"_{disc.validation}_"]
    return "\n".join(lines)


def add_discovery_panel(gui: viser.GuiApi, disc: Discovery | None
                        ) -> tuple[viser.GuiMarkdownHandle | None, list[viser.GuiImageHandle]]:
    """The "Effect discovery" folder (when there is something to show): its text and
    its figures' handles."""
    text = None
    images: list[viser.GuiImageHandle] = []
    if disc is not None and (disc.selected or disc.rms_before or disc.figures):
        with gui.add_folder("Effect discovery"):
            text = gui.add_markdown(discovery_markdown(disc))
            for fig in disc.figures:
                img = read_png(fig)
                if img is not None:
                    images.append(gui.add_image(img, label=fig.name, format="png"))
    return text, images


def add_figures_panel(gui: viser.GuiApi, run: Run) -> None:
    """The "Run figures" folder: a dropdown of the run's figures and the chosen one."""
    if not run.figures:
        return
    with gui.add_folder("Run figures", expand_by_default=False):
        names = [f.name for f in run.figures]
        choice = gui.add_dropdown("Figure", names, initial_value=names[0])
        first = read_png(run.figures[0])
        image = gui.add_image(first if first is not None else np.full((8, 8, 3), 255,
                              np.uint8), format="png")

        def show_figure(_) -> None:
            img = read_png(run.path / "figures" / choice.value)
            if img is not None:
                image.image = img
        choice.on_update(show_figure)


def add_warnings_panel(gui: viser.GuiApi, warnings: tuple[str, ...]) -> None:
    """The "Warnings" folder, when loading the run warned about anything."""
    if warnings:
        with gui.add_folder("Warnings", expand_by_default=False):
            gui.add_markdown("\n".join(f"- {w}" for w in warnings))
