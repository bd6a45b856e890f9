"""Tables and the figure of the apparent inertia against frequency
(``pinquad.realdata.response``, ``python -m pinquad.response``)."""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray

from pinquad.io.runs import atomic_write_bytes
from pinquad.realdata.response import UNEXPLAINED_BAND, ApparentInertia, SimulatedResponse

Array = NDArray[np.float64]

AXES = ("x (roll)", "y (pitch)", "z (yaw)")
REPORT_HZ = (2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0, 15.0)
BANDS = ((2.0, 3.0), (3.0, 5.0), (5.0, 8.0), (8.0, 12.0), (12.0, 16.0))
"""Frequency bands [Hz] of the printed band medians."""


def format_response(results: Sequence[ApparentInertia], hz: Sequence[float] = REPORT_HZ,
                    published: Array | None = None) -> str:
    """A Markdown table per axis: rows = logs, columns = frequencies, cells |H| [1e-6 kg m^2]
    (coherence, phase [deg])."""
    lines = []
    for j, axis in enumerate(AXES):
        ref = "" if published is None else f"; published {1e6 * published[j]:.2f}"
        lines.append(f"\naxis {axis}: |H| [1e-6 kg m^2] (coherence, phase: > 0 the torque "
                     f"leads){ref}\n")
        lines.append("| log | " + " | ".join(f"{f:g} Hz" for f in hz) + " |")
        lines.append("|---|" + "---|" * len(hz))
        for r in results:
            cells = []
            for f in hz:
                g, ph, c = r.at(f)
                cells.append(f"{1e6 * g[j]:.1f} ({c[j]:.2f}, {np.degrees(ph[j]):+.0f} deg)")
            lines.append(f"| {r.name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def plot_response(results: Sequence[ApparentInertia], path: Path,
                  published: Array | None = None, band: tuple[float, float] = (3.0, 8.0),
                  fmax: float = 20.0, reference_label: str = "published (CF 2.0)",
                  title: str = "apparent inertia against frequency (flat and on the dashed "
                               "line if the rigid-body torque model held)") -> Path:
    """|H_j(f)| of every log, one panel per axis, the inertia M-step's band shaded and the
    reference inertia ``published`` (3,) [kg m^2] dashed; written atomically to ``path``
    (PNG)."""
    fig = Figure(figsize=(13, 4))
    axes = fig.subplots(1, 3, sharex=True)
    for j, ax in enumerate(axes):
        for r in results:
            sel = (r.freq > 0.5) & (r.freq <= fmax)
            ax.plot(r.freq[sel], 1e6 * r.gain[sel, j], lw=1.2, label=r.name)
        ax.axvspan(*band, color="0.9", zorder=0, label=f"M-step band {band[0]:g}-{band[1]:g} Hz")
        if published is not None:
            ax.axhline(1e6 * published[j], color="k", ls="--", lw=1, label=reference_label)
        ax.set_yscale("log")
        ax.set_title(f"axis {AXES[j]}")
        ax.set_xlabel("frequency [Hz]")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("|torque / angular acceleration| [1e-6 kg m^2]")
    axes[-1].legend(fontsize=7, loc="upper right")
    fig.suptitle(title)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    return atomic_write_bytes(path, buf.getvalue())


def band_lines(results: Sequence[ApparentInertia], what: str) -> list[str]:
    """Per axis, the median over ``results`` of each band's median |H| [1e-6 kg m^2]."""
    return [f"\naxis {axis}, median over the {what} of the median |H| per band "
            "[1e-6 kg m^2]: " + ", ".join(
                f"{lo:g}-{hi:g} Hz {1e6 * np.median([r.band_gain(lo, hi)[j] for r in results]):.1f}"
                for lo, hi in BANDS)
            for j, axis in enumerate(AXES)]


def unexplained_line(r: ApparentInertia, against: str) -> str:
    lo, hi = UNEXPLAINED_BAND
    return (f"{r.name}: unexplained / rotor torque in {lo:g}-{hi:g} Hz (against {against}) "
            "roll {:.2f}, pitch {:.2f}, yaw {:.2f}".format(*r.unexplained))


def format_simulated(results: Sequence[SimulatedResponse]) -> str:
    """A Markdown table, one row per simulated flight: the band medians of |H| per axis,
    the unexplained torque ratio and EM's inertia error."""
    head = ("| torque noise | seed | sensor | axis | " + " | ".join(
        f"{lo:g}-{hi:g} Hz" for lo, hi in BANDS) + " | true I | unexplained / rotor torque "
        f"({UNEXPLAINED_BAND[0]:g}-{UNEXPLAINED_BAND[1]:g} Hz) | EM inertia error | "
        "measured-flight pipeline (band-passed M-step) inertia error |")
    lines = [head, "|---|---|---|---|" + "---|" * len(BANDS) + "---|---|---|---|"]
    for s in results:
        for j, axis in enumerate(("roll", "pitch", "yaw")):
            bands = " | ".join(f"{1e6 * s.response.band_gain(lo, hi)[j]:.1f}"
                               for lo, hi in BANDS)
            crash = " (crashed)" if s.crashed else ""
            lines.append(f"| x{s.factor:g}{crash} | {s.seed} | {s.sensor} | {axis} | {bands} | "
                         f"{1e6 * s.truth[j]:.2f} | {s.response.unexplained[j]:.2f} | "
                         f"{100 * s.em_rel_error[j]:+.1f} % | "
                         + (f"{100 * s.band_rel_error[j]:+.1f} % |"
                            if np.isfinite(s.band_rel_error[j]) else "- |"))
    return "\n".join(lines)

