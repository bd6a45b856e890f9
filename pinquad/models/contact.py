"""Floor contact found from the data: the steps where the vehicle rests on or strikes the
floor, from what any log carries (height, vertical velocity, collective thrust, attitude),
without a contact flag column.

Quantities on the log's uniform grid t_k = t_0 + k dt (rows k = 0 .. N-1):

* z_k [m] height (NaN where not sampled; linearly interpolated between samples),
  v_k [m/s] vertical velocity (the log's, interpolated; if the log has none, the central
  difference of z), F_k [N] collective thrust, c_k = R_33 = cos(roll) cos(pitch) the
  vertical component of the thrust axis (interpolated; 1 if never sampled).
* Floor level z_f [m]: the lowest *sustained* height, min_k of the running median of z
  over ``sustain`` seconds (a strike's brief dip into the floor, or a single low sample,
  does not move it; z = 0 is not assumed). "At the floor" means z_k - z_f < ``floor_band``.
* Free-flight vertical acceleration the logged thrust predicts,
  a_k = F_k c_k / m - g  [m/s^2],
  and its residual over a window of 2h rows centred on k,
  r_k = (v_{k+h} - v_{k-h} - dt sum_{i=k-h}^{k+h-1} a_i) / (2 h dt)  [m/s^2].
  m r_k is the mean vertical force the flight model lacks over the window,
  m dv/dt - (F R_33 - m g); the floor can only push up, so contact shows as r_k > 0.
* The mass m [kg] is a thrust balance over the rows clearly airborne
  (z_k - z_f > ``clearance``, at least ``min_airborne`` seconds of them):
  m = sum_k F_k c_k / sum_k ((v_{k+1} - v_k) / dt + g);
  over all rows when the log has less airborne time than that (a flat flight never
  climbs clear of its lowest level; a log spent wholly on the floor then shows no
  contact). The guess (sidecar or the vehicle's default) is used only if that balance
  is not positive. A 30 % wrong guess therefore does not move the detection; with the
  guess itself a hover at the floor level would read as a 0.3 g upward residual (and
  did on the brushless figure-8s, flown flat at 0.33-0.44 m with the brushed kf).

A step is in contact when it is at the floor and

* **resting**: |v_k| < ``rest_speed`` and the horizontal speed |v_xy,k| < ``rest_speed``
  (friction holds a vehicle on the floor; a pass low over the floor in ground effect,
  which also decelerates the vehicle with the thrust below its weight, moves
  sideways: jana20 at 6 cm, 0.3-0.5 m/s), and the residual over ``rest_window`` seconds
  r_k > max(``rest_accel``, ``noise_factor`` s_rest), i.e. the vehicle neither falls nor
  rises as the thrust says (thrust below weight, the floor carrying the rest); the whole
  run of steps at the floor that still, holding such a step, is marked; or
* **striking**: the residual over ``impact_window`` seconds r_k > max(``impact_accel``,
  ``noise_factor`` s_impact) with the height within ``floor_band`` of z_f somewhere in
  that window (the vertical velocity stopped or reversed abruptly at the floor level);
  the window's steps are marked.

s_rest, s_impact [m/s^2] are robust spreads (1.4826 x median absolute deviation) of the
two residuals on the steps not at the floor: the thresholds rise with the log's noise
and model error, so a noisy log does not fire on its noise. Ground effect at a
Crazyflie's lowest flights (z/R > 2) adds about 1 % of thrust, far below the thresholds.

Defaults (units): floor_band 0.02 m, sustain 0.2 s, clearance 0.05 m, min_airborne 1 s,
rest_window 0.3 s, rest_speed 0.1 m/s, rest_accel 0.3 m/s^2 (3 % of g), impact_window
0.03 s, impact_accel 3 m/s^2 (0.3 g), noise_factor 5, margin 0.05 s (the contact steps
are widened by it on both sides: touch-down and lift-off mix floor and flight forces
within a step or two, and the detector places them to a window's resolution).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pinquad.io.timebase import sampling_interval

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class ContactSettings:
    """Thresholds of :func:`detect_floor_contact` (module docstring): floor_band [m],
    sustain [s], clearance [m], min_airborne [s], rest_window [s], rest_speed [m/s],
    rest_accel [m/s^2], impact_window [s], impact_accel [m/s^2], noise_factor [-],
    margin [s]."""

    floor_band: float = 0.02
    sustain: float = 0.2
    clearance: float = 0.05
    min_airborne: float = 1.0
    rest_window: float = 0.3
    rest_speed: float = 0.1
    rest_accel: float = 0.3
    impact_window: float = 0.03
    impact_accel: float = 3.0
    noise_factor: float = 5.0
    margin: float = 0.05


@dataclass(frozen=True)
class ContactDetection:
    """Floor contact found in a log of N rows.

    contact (N,) bool: steps found resting on or striking the floor; resting, striking
    (N,) bool: which test found them; widened (N,) bool: contact grown by the margin on
    both sides (what the E-step and M-step treat as contact); floor_height [m]: z_f;
    mass [kg]: the mass in a_k; mass_from: ``data`` (thrust balance) or ``guess``;
    rest_threshold, impact_threshold [m/s^2]: the thresholds used on r_k.
    """

    contact: BoolArray
    resting: BoolArray
    striking: BoolArray
    widened: BoolArray
    floor_height: float
    mass: float
    mass_from: str
    rest_threshold: float
    impact_threshold: float

    @property
    def n_steps(self) -> int:
        return int(self.contact.sum())

    def describe(self) -> str:
        """One line: what was found and from what."""
        return (f"{int(self.resting.sum())} steps resting, {int(self.striking.sum())} striking, "
                f"floor at z = {self.floor_height:+.3f} m, mass {self.mass * 1e3:.1f} g from the "
                f"{'thrust balance' if self.mass_from == 'data' else 'guess'}; widened by "
                "the margin")


def _fill(t: Array, x: Array) -> Array:
    """x (N,) with NaNs linearly interpolated (held at the ends); all-NaN stays NaN."""
    ok = np.isfinite(x)
    if ok.all() or not ok.any():
        return x.copy()
    return np.interp(t, t[ok], x[ok])


def _running_median(x: Array, half: int) -> Array:
    """Median of the finite values of x over rows [k - half, k + half] (NaN if none)."""
    if half < 1:
        return x.copy()
    pad = np.pad(x, half, constant_values=np.nan)
    win = np.lib.stride_tricks.sliding_window_view(pad, 2 * half + 1)
    out = np.full(x.shape, np.nan)
    ok = np.isfinite(win).any(axis=1)
    out[ok] = np.nanmedian(win[ok], axis=1)
    return out


def window_residual(v: Array, accel: Array, dt: float, half: int) -> Array:
    """r_k (N,) [m/s^2] (module docstring): measured minus predicted change of v over
    rows k - half .. k + half, per second; NaN within ``half`` rows of the ends."""
    n = v.size
    out = np.full(n, np.nan)
    if n <= 2 * half or half < 1:
        return out
    csum = np.concatenate([[0.0], np.cumsum(accel)])
    k = np.arange(half, n - half)
    predicted = dt * (csum[k + half] - csum[k - half])
    out[k] = (v[k + half] - v[k - half] - predicted) / (2 * half * dt)
    return out


def _spread(r: Array, rows: BoolArray) -> float:
    vals = r[rows & np.isfinite(r)]
    if vals.size < 10:
        vals = r[np.isfinite(r)]
    if vals.size == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(vals - np.median(vals))))


def touching_transitions(rows: BoolArray) -> BoolArray:
    """(N - 1,) bool: transition k -> k+1 touches a marked row of ``rows`` (N,) at either
    end (the transitions floor contact, or any other marked stretch, takes out)."""
    rows = np.asarray(rows, dtype=bool)
    return rows[:-1] | rows[1:]


def _dilate(mask: BoolArray, rows: int) -> BoolArray:
    if rows < 1 or not mask.any():
        return mask.copy()
    return np.convolve(mask.astype(float), np.ones(2 * rows + 1), mode="same") > 0.5


def _runs_touching(candidate: BoolArray, seed: BoolArray) -> BoolArray:
    """The contiguous runs of ``candidate`` that contain a ``seed`` step."""
    out = np.zeros_like(candidate)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], candidate.astype(np.int8), [0]])))
    for start, stop in zip(edges[::2], edges[1::2], strict=True):
        if seed[start:stop].any():
            out[start:stop] = True
    return out


def thrust_balance_mass(v: Array, thrust_up: Array, dt: float, rows: BoolArray,
                        gravity: float) -> float:
    """m [kg] = sum F c / sum (dv/dt + g) over the transitions k -> k+1 with both rows in
    ``rows`` (module docstring); NaN if there are none."""
    use = rows[:-1] & rows[1:] & np.isfinite(v[:-1]) & np.isfinite(v[1:]) & np.isfinite(thrust_up[:-1])
    if not use.any():
        return float("nan")
    acc = np.diff(v)[use] / dt
    return float(thrust_up[:-1][use].sum() / (acc + gravity).sum())


def detect_floor_contact(t: Array, height: Array, vertical_velocity: Array | None,
                         thrust: Array, tilt: Array | None, mass_guess: float,
                         gravity: float = 9.81, settings: ContactSettings | None = None,
                         horizontal_speed: Array | None = None) -> ContactDetection:
    """Find the steps where the vehicle rests on or strikes the floor (module docstring).

    t (N,) [s] (dt: their median step); height (N,) [m] world z (NaN: not sampled); vertical_velocity
    (N,) [m/s] or None (then differentiated from the height); horizontal_speed (N,)
    [m/s] or None (not used, NaN rows interpolated); thrust (N,) [N]; tilt (N,)
    R_33 [-] or None (level); mass_guess [kg]; gravity [m/s^2]. NaN thrust or tilt
    rows are interpolated.
    """
    s = settings or ContactSettings()
    t = np.asarray(t, dtype=float)
    n = t.size
    none = np.zeros(n, dtype=bool)
    z = _fill(t, np.asarray(height, dtype=float))
    if n < 3 or not np.isfinite(z).any():
        return ContactDetection(none, none, none, none, float("nan"), float(mass_guess),
                                "guess", float("nan"), float("nan"))
    dt = sampling_interval(t)  # the log's own step: a gap or jitter does not stretch it
    v = None if vertical_velocity is None else _fill(t, np.asarray(vertical_velocity, float))
    if v is None or not np.isfinite(v).any():
        v = np.gradient(z, t)
    c = np.ones(n) if tilt is None else _fill(t, np.asarray(tilt, dtype=float))
    c = np.where(np.isfinite(c), c, 1.0)
    thrust_up = _fill(t, np.asarray(thrust, dtype=float)) * c

    sampled = np.asarray(height, dtype=float)
    floor = float(np.nanmin(_running_median(sampled, max(1, round(0.5 * s.sustain / dt)))))
    above = z - floor
    at_floor = above < s.floor_band
    airborne = above > s.clearance

    # A log that never climbs clear of its lowest level is a flat flight far more often
    # than a log spent on the floor: balance over all its rows then.
    balance_rows = airborne if airborne.sum() * dt >= s.min_airborne else np.ones(n, bool)
    mass, mass_from = float(mass_guess), "guess"
    m_data = thrust_balance_mass(v, thrust_up, dt, balance_rows, gravity)
    if np.isfinite(m_data) and m_data > 0:
        mass, mass_from = m_data, "data"
    accel = np.nan_to_num(thrust_up / mass - gravity)

    h_rest = max(1, round(0.5 * s.rest_window / dt))
    h_imp = max(1, round(0.5 * s.impact_window / dt))
    r_rest = window_residual(v, accel, dt, h_rest)
    r_imp = window_residual(v, accel, dt, h_imp)
    thr_rest = max(s.rest_accel, s.noise_factor * _spread(r_rest, ~at_floor))
    thr_imp = max(s.impact_accel, s.noise_factor * _spread(r_imp, ~at_floor))

    still = at_floor & (np.abs(v) < s.rest_speed)
    if horizontal_speed is not None:
        sideways = _fill(t, np.asarray(horizontal_speed, dtype=float))
        still &= ~(sideways >= s.rest_speed)  # NaN (never sampled): not used
    rest_seed = still & (np.nan_to_num(r_rest, nan=-np.inf) > thr_rest)
    resting = _runs_touching(still, rest_seed)
    floor_near = _dilate(at_floor, h_imp)
    strike_seed = floor_near & (np.nan_to_num(r_imp, nan=-np.inf) > thr_imp)
    striking = _dilate(strike_seed, h_imp) & ~resting
    contact = resting | striking
    widened = _dilate(contact, round(s.margin / dt))
    return ContactDetection(contact, resting, striking, widened, floor, mass, mass_from,
                            thr_rest, thr_imp)


@dataclass(frozen=True)
class FloorLevel:
    """The floor's height in the log's frame, from which discovery's ground-effect law
    measures the vehicle's height (``Observations.floor``).

    height z_f [m, world]; source: ``flags`` (the median logged height over the rows a
    simulator flags as resting on the floor, when they last ``ContactSettings.sustain``),
    ``contact`` (contact found from the data, ``detect_floor_contact``: its floor level,
    the lowest height the vehicle sustains, ``ContactDetection.floor_height``) or
    ``none`` (no contact in the log, or contact flags too brief to place the floor:
    z_f = 0, the origin of the log's frame, taken as the floor); rows: how many contact
    rows it came from."""

    height: float
    source: str
    rows: int = 0

    def describe(self) -> str:
        """One line for the report: where the ground-effect law puts the floor."""
        if self.source == "flags":
            return (f"floor at z = {self.height:+.3f} m: the median height over the "
                    f"{self.rows} rows the log flags as resting on it")
        if self.source == "contact":
            return (f"floor at z = {self.height:+.3f} m: the lowest height the vehicle "
                    f"sustains, in a log whose {self.rows} contact rows show the floor")
        if self.rows:
            return (f"floor at z = 0 (the log's frame origin): its {self.rows} contact rows "
                    "are too brief to place the floor")
        return ("floor at z = 0 (the log's frame origin): the log shows no floor contact "
                "to find it from")


NO_FLOOR = FloorLevel(0.0, "none")
"""A log without floor contact: the ground-effect law takes the floor at z = 0."""


def floor_level(height: Array, flags: BoolArray | None, min_rows: int,
                contact: BoolArray | None = None, lowest: float = float("nan")) -> FloorLevel:
    """Where the log shows the floor (``FloorLevel``). height (N,) [m] world z (NaN: not
    sampled); flags (N,) bool or None: a simulator's contact flags (the rows its vehicle
    rests on the floor); min_rows: the fewest sampled flagged rows whose median places
    the floor (``ContactSettings.sustain`` seconds of rows: a single position sample is
    off by its noise, millimetres, which moves a ground-effect gain measured a few
    centimetres up by several per cent); contact (N,) bool or None: the contact rows
    found from the data (resting or striking); lowest [m]: the detector's floor level,
    the lowest height sustained over ``ContactSettings.sustain``.

    The flags, when given, decide alone. A vehicle on the floor stands at its lowest
    sustained height: the law's z is then the height above that level, as in the
    simulators, whose vehicles rest at z = 0. Of a log whose contact is found from the
    data, the floor level is taken rather than the median height of the rows found
    resting: a Parrot-frame random walk "rests" 0.5-1.2 cm above its floor level
    (hovering in ground effect at the floor, where the thrust no longer balances
    the weight), and its floor level is the data set's stated floor plane within 4 mm."""
    z = np.asarray(height, dtype=float)
    if flags is not None:
        on = np.asarray(flags, dtype=bool) & np.isfinite(z)
        if on.sum() >= max(min_rows, 1):
            return FloorLevel(float(np.median(z[on])), "flags", int(on.sum()))
        return FloorLevel(0.0, "none", int(on.sum()))
    if contact is not None and np.any(contact) and np.isfinite(lowest):
        return FloorLevel(float(lowest), "contact", int(np.sum(contact)))
    return NO_FLOOR
