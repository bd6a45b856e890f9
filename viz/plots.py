"""The parameter-history plots of a run's view: mass and the inertia diagonal per EM
iteration or online update (uPlot, through viser), beside the truth when the run knows
it. Display units: g and 1e-6 kg m^2.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from viz.run import CycleRecord, decimate_indices

if TYPE_CHECKING:
    import viser

Array = NDArray[np.float64]

TRUTH_CSS = "#198c3c"
ESTIMATE_CSS = "#eb6e14"
AXIS_CSS = ("#d6336c", "#1c7ed6", "#7048e8")
MAX_PLOT_POINTS = 2000
"""Samples per parameter-history series (online runs may have thousands of updates)."""


@dataclass(frozen=True)
class PlotData:
    """A parameter history in display units, decimated: x (K,); mass (K,) [g];
    inertia (K, 3) [1e-6 kg m^2]; the truth as constant series (None if unknown)."""

    x: Array
    mass: Array
    inertia: Array
    true_mass: Array | None
    true_inertia: Array | None

    def mass_columns(self) -> tuple[Array, ...]:
        """uPlot columns: x, the mass estimate [g], the truth if known."""
        return (self.x, self.mass) + (() if self.true_mass is None else (self.true_mass,))

    def inertia_columns(self) -> tuple[Array, ...]:
        """uPlot columns: x, Ixx, Iyy, Izz [1e-6 kg m^2], their truths if known."""
        cols = tuple(self.inertia[:, k] for k in range(3))
        true = () if self.true_inertia is None else tuple(self.true_inertia[:, k]
                                                          for k in range(3))
        return (self.x, *cols, *true)

    def mass_scales(self) -> dict:
        """uPlot scales of the mass plot (y framed by :func:`focus_range`)."""
        return {"x": {"time": False}, "y": {"range": focus_range(self.mass, self.true_mass)}}

    def inertia_scales(self) -> dict:
        """uPlot scales of the inertia plot (y framed by :func:`focus_range`)."""
        return {"x": {"time": False},
                "y": {"range": focus_range(self.inertia, self.true_inertia)}}


def focus_range(values: Array, truth: Array | None) -> tuple[float, float]:
    """y range of a history that leaves out the first tenth (at least the initial guess):
    EM starts far off (m0 = 1 g against 180 g), and auto-ranging on that start would
    flatten the convergence the plot is for."""
    n = values.shape[0]
    tail = values[min(max(1, n // 10), n - 1):] if n > 1 else values
    parts = [tail.reshape(-1)] + ([] if truth is None else [truth.reshape(-1)])
    data = np.concatenate(parts)
    data = data[np.isfinite(data)]
    if data.size == 0:
        return (0.0, 1.0)
    lo, hi = float(data.min()), float(data.max())
    pad = max(0.15 * (hi - lo), 0.03 * max(abs(lo), abs(hi)), 1e-9)
    return (lo - pad, hi + pad)


def plot_data(rec: CycleRecord) -> PlotData:
    """History in display units (g, 1e-6 kg m^2), decimated; truth as constant series."""
    idx = decimate_indices(rec.x.shape[0], MAX_PLOT_POINTS)
    x = rec.x[idx]
    if x.shape[0] < 2:
        # uPlot needs two points to draw a line; repeat the single estimate.
        idx = np.array([idx[0], idx[0]])
        x = np.array([x[0], x[0] + 1.0])
    n = x.shape[0]
    return PlotData(
        x=x, mass=rec.mass[idx] * 1e3, inertia=rec.inertia_diag[idx] * 1e6,
        true_mass=None if rec.true_mass is None else np.full(n, rec.true_mass * 1e3),
        true_inertia=(None if rec.true_inertia_diag is None
                      else np.broadcast_to(rec.true_inertia_diag * 1e6, (n, 3)).copy()),
    )




def add_parameter_plots(gui: viser.GuiApi, rec: CycleRecord
                        ) -> tuple[viser.GuiUplotHandle, viser.GuiUplotHandle]:
    """Add the mass and inertia-diagonal plots of ``rec`` to ``gui``; their handles."""
    # deferred on purpose: viser is the viewer's optional, heavy dependency
    from viser import uplot

    d = plot_data(rec)
    xs: uplot.Series = {"label": rec.x_label}
    mass_series: list[uplot.Series] = [xs, {"label": "mass", "stroke": ESTIMATE_CSS,
                                            "width": 2}]
    if d.true_mass is not None:
        mass_series.append({"label": "true", "stroke": TRUTH_CSS, "width": 1.5,
                            "dash": (6.0, 4.0)})
    mass_plot = gui.add_uplot(d.mass_columns(), tuple(mass_series),
                              title="mass [g]", scales=d.mass_scales(), aspect=2.2)
    in_series: list[uplot.Series] = [xs]
    for k, axis in enumerate(("xx", "yy", "zz")):
        in_series.append({"label": f"I{axis}", "stroke": AXIS_CSS[k], "width": 2})
    if d.true_inertia is not None:
        for k, axis in enumerate(("xx", "yy", "zz")):
            in_series.append({"label": f"true I{axis}", "stroke": AXIS_CSS[k],
                              "width": 1.2, "dash": (6.0, 4.0)})
    inertia_plot = gui.add_uplot(d.inertia_columns(), tuple(in_series),
                                 title="inertia diagonal [1e-6 kg m²]",
                                 scales=d.inertia_scales(), aspect=1.8)
    return mass_plot, inertia_plot


def loglik_columns(rec: CycleRecord) -> tuple[Array, Array]:
    """uPlot columns of the log-likelihood plot: x and log p(y | iterate) [nats] (NaN
    where the run recorded none: uPlot leaves a gap)."""
    idx = decimate_indices(rec.x.shape[0], MAX_PLOT_POINTS)
    ll = np.full(rec.x.shape[0], np.nan) if rec.loglik is None else rec.loglik
    x, y = rec.x[idx], ll[idx]
    if x.shape[0] < 2:
        x, y = np.array([x[0], x[0] + 1.0]), np.array([y[0], y[0]])
    return x, y


def add_loglik_plot(gui: viser.GuiApi, rec: CycleRecord) -> viser.GuiUplotHandle:
    """Add the log-likelihood-per-iterate plot of ``rec`` to ``gui``; its handle."""
    # deferred on purpose: viser is the viewer's optional, heavy dependency
    from viser import uplot

    series: tuple[uplot.Series, ...] = ({"label": rec.x_label},
                                        {"label": "log-likelihood", "stroke": ESTIMATE_CSS,
                                         "width": 2})
    return gui.add_uplot(loglik_columns(rec), series, title="log-likelihood [nats]",
                         scales={"x": {"time": False}}, aspect=2.2)
