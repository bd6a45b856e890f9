"""Apparent inertia against frequency on a measured flight: a model-free look at how far
the rigid-body torque model holds, band by band.

For each body axis j the rotor torque tau_j [N m] (measured rotor speeds through the
actuator model, plus J_r sum_i spin_i omega_i' on the yaw axis) is compared with the
gyro's angular acceleration a_j = d(gyro_j)/dt [rad/s^2] through Welch spectra:

    H_j(f) = S_{a tau}(f) / S_{a a}(f)   [kg m^2],
    gamma_j^2(f) = |S_{a tau}|^2 / (S_{a a} S_{tau tau})   (coherence, 0..1).

Where I_jj a_j = tau_j holds, |H_j| = I_jj at every frequency with zero phase; a |H_j|
that changes with f means the torque model (or the measurement timing) misses a dynamic
element, and the band the inertia M-step uses then decides the identified inertia. The
gyroscopic term (omega x I omega) and the air-speed moments are left out: it is a
diagnostic, not an estimator. Phase > 0: the modelled torque leads the acceleration (the
gyro's filtering delays it; the 10 ms grid puts the torque bin half a step late, which is
undone here by centring both on the grid times).

``python -m pinquad.response [LOG ...]`` prints |H| and the coherence per axis at a few
frequencies for each log, and draws |H_j(f)| of every log in one figure.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

AXES = ("x (roll)", "y (pitch)", "z (yaw)")
REPORT_HZ = (2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0, 15.0)


@dataclass(frozen=True)
class ApparentInertia:
    """The torque / angular-acceleration frequency response of one flight.

    name: log name; freq (F,) [Hz]; gain (F, 3) [kg m^2]: |H_j(f)|; phase (F, 3) [rad]:
    arg H_j(f); coherence (F, 3) [-]; rotor_inertia [kg m^2]: the J_r added to the yaw
    torque; seconds: length of the analysed span [s].
    """

    name: str
    freq: Array
    gain: Array
    phase: Array
    coherence: Array
    rotor_inertia: float
    seconds: float

    def at(self, hz: float) -> tuple[Array, Array, Array]:
        """(gain (3,), phase (3,), coherence (3,)) at the frequency bin nearest ``hz``."""
        k = int(np.argmin(np.abs(self.freq - hz)))
        return self.gain[k], self.phase[k], self.coherence[k]

    def band_gain(self, lo: float, hi: float) -> Array:
        """(3,) [kg m^2] median of |H_j| over the bins in [lo, hi] Hz."""
        sel = (self.freq >= lo) & (self.freq <= hi)
        return np.median(self.gain[sel], axis=0)


def _used_span(exclude: NDArray[np.bool_]) -> slice:
    """Grid steps from the first to the last used transition (take-off and landing cut)."""
    used = np.flatnonzero(~exclude[:-1])
    if used.size < 2:
        raise ValueError("fewer than two used transitions: nothing to analyse")
    return slice(int(used[0]), int(used[-1]) + 2)


def apparent_inertia(real, name: str = "", rotor_inertia: float = 0.0,
                     segment_s: float = 2.56) -> ApparentInertia:
    """:class:`ApparentInertia` of a measured flight (``realdata.RealObservations``).

    Torque bins cover [t_k, t_k + dt) and gyro bins are centred on t_k, so the torque is
    averaged over neighbouring bins, (tau_{k-1} + tau_k) / 2, to centre it on t_k as
    well; a_k is the central difference of the gyro. Spectra: Welch, Hann segments of
    ``segment_s`` seconds, half overlap, over the span between the first and the last
    used transition (gaps inside it interpolated)."""
    from scipy.signal import csd, welch

    obs = real.obs
    dt = obs.dt
    span = _used_span(obs.exclude)
    t = obs.t[span]
    gyro = np.asarray(real.log.gyro, dtype=float)[span]
    seen = np.isfinite(gyro).all(axis=1)
    if seen.sum() < 2:
        raise ValueError(f"{real.source}: no gyro samples in the used span")
    gyro = np.column_stack([np.interp(t, t[seen], gyro[seen, j]) for j in range(3)])
    acc = np.gradient(gyro, dt, axis=0)
    torque = np.asarray(obs.inputs, dtype=float)[:, 1:4].copy()
    if rotor_inertia and real.rotor_acc is not None:
        torque[:, 2] += rotor_inertia * real.rotor_acc
    centred = torque.copy()
    centred[1:] = 0.5 * (torque[1:] + torque[:-1])
    tau = centred[span]
    fs = 1.0 / dt
    nper = min(int(round(segment_s * fs)), t.size)
    gain, phase, coh = [], [], []
    freq = np.zeros(0)
    for j in range(3):
        freq, s_at = csd(acc[:, j], tau[:, j], fs=fs, nperseg=nper)
        _, s_aa = welch(acc[:, j], fs=fs, nperseg=nper)
        _, s_tt = welch(tau[:, j], fs=fs, nperseg=nper)
        with np.errstate(divide="ignore", invalid="ignore"):
            h = s_at / s_aa
            coh.append(np.abs(s_at) ** 2 / (s_aa * s_tt))
        gain.append(np.abs(h))
        phase.append(np.angle(h))
    return ApparentInertia(name=name or Path(real.source).name, freq=freq,
                           gain=np.column_stack(gain), phase=np.column_stack(phase),
                           coherence=np.column_stack(coh), rotor_inertia=float(rotor_inertia),
                           seconds=float(t[-1] - t[0]))


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
                  fmax: float = 20.0) -> Path:
    """|H_j(f)| of every log, one panel per axis, the inertia M-step's band shaded and the
    published inertia dashed; written atomically to ``path`` (PNG)."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pinquad.runs import atomic_write_bytes

    fig, axes = plt.subplots(1, 3, figsize=(13, 4), sharex=True)
    for j, ax in enumerate(axes):
        for r in results:
            sel = (r.freq > 0.5) & (r.freq <= fmax)
            ax.plot(r.freq[sel], 1e6 * r.gain[sel, j], lw=1.2, label=r.name)
        ax.axvspan(*band, color="0.9", zorder=0, label=f"M-step band {band[0]:g}-{band[1]:g} Hz")
        if published is not None:
            ax.axhline(1e6 * published[j], color="k", ls="--", lw=1, label="published (CF 2.0)")
        ax.set_yscale("log")
        ax.set_title(f"axis {AXES[j]}")
        ax.set_xlabel("frequency [Hz]")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("|torque / angular acceleration| [1e-6 kg m^2]")
    axes[-1].legend(fontsize=7, loc="upper right")
    fig.suptitle("apparent inertia against frequency (flat and on the dashed line if the "
                 "rigid-body torque model held)")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return atomic_write_bytes(path, buf.getvalue())


def main(argv: Sequence[str] | None = None) -> int:
    from tqdm import tqdm

    from pinquad.logs import LogFormatError
    from pinquad.realdata import (
        POOL_FLIGHTS,
        PUBLISHED_INERTIA,
        RealDataOptions,
        flights_dir,
        load_real,
        stand_dir,
        thrust_coefficient,
    )

    p = argparse.ArgumentParser(
        prog="python -m pinquad.response",
        description="Apparent inertia |torque / angular acceleration| against frequency on "
                    "measured Crazyflie flights: where the rigid-body torque model holds.")
    p.add_argument("logs", nargs="*", default=list(POOL_FLIGHTS),
                   help="log names in the data directory, or paths (default: the seven clean "
                        "logs)")
    p.add_argument("--data", type=Path, default=None,
                   help="Crazyflie data directory (default: $PINQUAD_CRAZYFLIE_DATA, else "
                        "../shared/data/crazyflie next to the repository)")
    p.add_argument("--rotor-inertia", type=float, default=0.0,
                   help="J_r [kg m^2] added to the yaw torque as J_r sum spin_i omega_i'")
    p.add_argument("--out", type=Path, default=None,
                   help="write the figure here (PNG; default: none)")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    flights = flights_dir(args.data)
    try:
        kf = thrust_coefficient(stand_dir(args.data))
        results = []
        for name in tqdm(args.logs, unit="log", file=sys.stderr):
            path = Path(name) if Path(name).exists() else flights / name
            real = load_real(path, RealDataOptions(), kf)
            results.append(apparent_inertia(real, path.name, args.rotor_inertia))
    except (LogFormatError, ValueError, FileNotFoundError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"apparent inertia |H_j(f)| = |S_a,tau / S_a,a| per axis, J_r = "
          f"{args.rotor_inertia:g} kg m^2 on the yaw torque; {len(results)} logs from {flights}")
    print(format_response(results, published=PUBLISHED_INERTIA))
    for j, axis in enumerate(AXES):
        print(f"\naxis {axis}, median over the logs of the median |H| per band "
              "[1e-6 kg m^2]: " + ", ".join(
                  f"{lo:g}-{hi:g} Hz {1e6 * np.median([r.band_gain(lo, hi)[j] for r in results]):.1f}"
                  for lo, hi in ((2.0, 3.0), (3.0, 5.0), (5.0, 8.0), (8.0, 12.0), (12.0, 16.0))))
    if args.out is not None:
        try:
            print(f"figure: {plot_response(results, args.out, PUBLISHED_INERTIA)}")
        except OSError as exc:
            print(f"error: {args.out}: cannot write the figure ({exc.strerror or exc})",
                  file=sys.stderr)
            return 2
    print(f"{len(results)} logs in {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
