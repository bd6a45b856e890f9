"""Grid bins of a measured flight without an actuation value, and why: a log gap, a log
sampled about as fast as the grid, or rotor speeds that are not finite.

The grid (``realdata.observations``, 10 ms) takes each input as the mean of the rows in
[t_k, t_k + dt). A log at about the grid's rate whose clock jitters by a few ms leaves
some bins without a row and puts two in others: that is sampling, not a gap, and the
input there is interpolated from the rows on either side (the transition is used). Only
a step between rows that ``pinquad.io.timebase`` calls a log gap (judged on the log's own
median step) cuts the flight: the transitions over it are excluded and are resets for
the E-step (``Observations.resets``: nothing says how the vehicle moved there, so the
smoother does not carry the flight dynamics across it). A bin that has rows but no
finite wrench (a non-finite rotor speed) is excluded as before.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pinquad.io.timebase import find_gaps, gap_transitions
from pinquad.realdata.resample import bin_mean

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

GAP_REASON = "log gaps"
"""How the exclusion of the transitions over log gaps begins."""


@dataclass(frozen=True)
class InputHoles:
    """Why grid rows (K,) have no input: gap, transitions over a log gap (excluded,
    resets); sparse, bins without a row outside gaps (input interpolated, used);
    bad, bins with rows but no finite wrench (excluded); gaps: the log gaps in words;
    interval [s]: the log's median step."""

    gap: BoolArray
    sparse: BoolArray
    bad: BoolArray
    gaps: str
    interval: float

    def exclusions(self) -> tuple[tuple[str, str, BoolArray], ...]:
        """(kind, reason, rows) of the transitions to exclude (kinds as
        ``identification.measured.EXCLUSION_KINDS``)."""
        return (("log gaps", f"{GAP_REASON}: {self.gaps} (resets for the E-step)", self.gap),
                ("no actuation", "bins with rows but no finite rotor speed", self.bad))

    def note(self, dt: float) -> str | None:
        """What was done with the bins without a row outside gaps, or None if none."""
        n = int(self.sparse.sum())
        if not n:
            return None
        return (f"{n} of {self.sparse.size} grid steps have no row of the log (its median "
                f"step {self.interval * 1e3:.2f} ms against the grid's {dt * 1e3:.0f} ms, and "
                "its clock's jitter): not gaps; their inputs are interpolated from the rows "
                "on either side and used")


def input_holes(t: Array, grid: Array, dt: float, nan_in: BoolArray) -> InputHoles:
    """The holes of the binned inputs (module docstring): rows at times t (N,) [s], grid
    (K,) [s] of step dt [s], nan_in (K,) bins whose input is NaN."""
    k = grid.size
    rows = np.isfinite(bin_mean(t, np.ones(t.size), grid, dt, k)[:, 0])
    gaps = find_gaps(t)
    gap = gap_transitions(gaps, grid, dt)
    no_row = nan_in & ~rows
    return InputHoles(gap=gap, sparse=no_row & ~gap, bad=nan_in & rows, gaps=gaps.describe(),
                      interval=gaps.interval)
