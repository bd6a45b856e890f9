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
from viz.run import CycleRecord, Discovery, Flight, Run

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


def header_markdown(run: Run, scale: float) -> str:
    """The view's first line: run, kind, vehicle (drawn ``scale`` times its size) and
    the legend of the paths it has."""
    legend = []
    if any(f.true_pos is not None for f in run.flights):
        legend.append(f"<span style='color:{TRUTH_CSS}'>&#9644;</span> true path")
    if any(f.est_pos is not None for f in run.flights):
        legend.append(f"<span style='color:{ESTIMATE_CSS}'>&#9644;</span> estimated path "
                      "(dashed)")
    return (f"**{run.path.name}** &middot; {run.kind} run &middot; vehicle `{run.vehicle}` "
            f"(drawn x{scale:.3g})  \n" + " &nbsp; ".join(legend))


def parameter_markdown(rec: CycleRecord) -> str:
    """Table of the final estimates of ``rec`` (g, 1e-6 kg m^2) beside the truth."""
    rows = ["| | estimate | truth | error |", "|---|---|---|---|"]
    truth = [rec.true_mass] + ([None] * 3 if rec.true_inertia_diag is None
                               else list(rec.true_inertia_diag))
    ests = [rec.est_mass, *rec.est_inertia_diag]
    for name, unit, k, est, tru in zip(("mass", "Ixx", "Iyy", "Izz"),
                                       ("g", "1e-6 kg m²", "1e-6 kg m²", "1e-6 kg m²"),
                                       (1e3, 1e6, 1e6, 1e6), ests, truth, strict=True):
        tru_txt = "-" if tru is None else f"{tru * k:.4g}"
        rows.append(f"| {name} [{unit}] | {est * k:.4g} | {tru_txt} | {fmt_pct(est, tru)} |")
    n = rec.x.shape[0]
    return (f"Sensor {rec.sensor}, cycle {rec.cycle}, {rec.mstep} M-step, "
            f"{n} {'updates' if rec.x_label != 'EM iteration' else 'iterations'}\n\n"
            + "\n".join(rows))


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
