"""A verdict for every estimate: can this log carry this number?

Each identified parameter (mass, I_xx, I_yy, I_zz, and the products of inertia of the
ten-parameter model) gets one of ``VERDICTS``, judged from data by three checks:

* identifiable: the log narrows the parameter to a small part of what the vehicle could
  physically be: the +-2 standard-error interval covers at most ``max_range_share`` of
  the vehicle's range (``VehicleRange``: its URDF values, or the sidecar's guesses, times
  and over a factor), 4 se <= share (hi - lo); for the inertia also the logged torques
  explain at least ``min_torque_share`` of the variance of the angular acceleration on
  the smoothed states (``torque_share``), the share R^2 = max(corr(d omega / dt,
  J^{-1} (tau - omega x J omega)), 0)^2 per body axis: if the torque channel cannot
  predict how the body turns, no inertia can be read from it, whatever its standard error;
  and the logged torques stand out from the process noise by ``min_torque_excitation``
  (``torque_excitation``): torques no larger than the unlogged disturbances are mostly a
  fast controller's answers to them, and an inertia read from those is biased (on
  closed-loop flights of an independent simulator: +45 to +90 %, standard error 3 %);
  and the fit is not held by the physical set: no parameter on the edge of the range EM
  searched, no inertia on a face of the triangle inequalities (``edges.triangle_face``),
  no error estimate that collapsed (``edges.collapsed_errors``);
* adequate: the model explains the data the parameter rests on: the mean normalised
  innovation squared of the EKF at the estimate, per measured channel and per row
  (``innovation_consistency``; 1 when the innovations are as large as the model says) is
  at most ``max_nis_ratio`` on the channels the parameter rests on (mass: pos, vel; the
  inertia: euler, gyro);
  and it agrees with the vehicle file's reference (``reference``; a mass that disagrees
  makes the inertia not adequate too);
* plausible: the values are physically possible: positive, principal moments obeying the
  triangle inequality (I_1 + I_2 >= I_3), positive definite tensor, within the vehicle's
  range.

Every route's verdicts are made here, from one ``VerdictEvidence`` (gathered from a fit
by ``verdict_evidence.data_evidence`` and the route's own findings): the vehicle estimate of a
recorded log, a measured flight, an online replay window or the known-mass EM route
(``judge``: mass and inertia), and each single number of the known-mass route
(``judge_estimate``: the thrust curve, the motor time constant, a moment of inertia),
which is also

* not identifiable when its total standard error exceeds ``max_rel_se`` of its value,
  when the fit does not determine it (``VerdictEvidence.undetermined``: the time
  constant's profile reaching the end of its grid, or resting at 0 below the rows'
  resolution; I_zz without the yaw torque coefficient) or when EM did not converge;
* not adequate when the regression it comes from explains less than ``min_fit_share``
  of the variance it fits (``ExplainedShare``), or when the inertia read on the lower
  and upper halves of the torque band lies more than ``max_band_shift`` combined
  statistical errors apart (``BandHalves``): the torque model is wrong in a frequency-
  dependent way;
* implausible when a moment of inertia is not positive;

and takes the verdict of the vehicle estimate it is part of (``part_of``, EM's). A
batch's between-flight scatter can only lower a verdict (``scaled_error_verdicts``).

A parameter failing several checks takes the most severe label (``VERDICTS`` order), and
keeps every reason (strings with the numbers). The overall verdict of an estimate is the
most severe of its parameters'. The thresholds are ``VerdictThresholds``; they were set
before they were measured on any log (docs/verdict.md has the measured values).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from pinquad.core.params import VEHICLES, VehicleRange
from pinquad.core.vehicle_file import is_vehicle_file, load_vehicle
from pinquad.identification.edges import triangle_face
from pinquad.identification.mass_balance import balance_check
from pinquad.identification.reference import ReferenceValues, reference_check, vehicle_mismatch

Array = NDArray[np.float64]

TRUSTED = "trusted"
IMPLAUSIBLE = "implausible"
NOT_ADEQUATE = "model not adequate"
NOT_IDENTIFIABLE = "not identifiable"
NOT_JUDGED = "not judged"
VERDICTS = (TRUSTED, NOT_JUDGED, IMPLAUSIBLE, NOT_ADEQUATE, NOT_IDENTIFIABLE)
NO_STDERR = ("no standard error (point estimates only, as the paper's closed-form M-step "
             "gives): nothing to judge the number by")
"""The verdicts, least severe first (the overall verdict is the most severe)."""

DIAGONAL = ("I_xx", "I_yy", "I_zz")
PRODUCTS = (("I_xy", 0, 1), ("I_xz", 0, 2), ("I_yz", 1, 2))
MASS_CHANNELS = ("pos", "vel")
INERTIA_CHANNELS = ("euler", "gyro")


@dataclass(frozen=True)
class VerdictThresholds:
    """What the checks demand (module docstring).

    mass_factor, inertia_factor [-]: the vehicle's range is nominal / factor .. nominal *
    factor; max_range_share [-]: largest share of that range the +-2 se interval may
    cover; min_torque_share [-]: smallest share of the angular-acceleration variance the
    torques must explain; max_nis_ratio [-]: largest mean normalised innovation squared
    per row of a channel the parameter rests on; max_input_shift [-]: largest relative
    change of an estimate between the two readings of a sampled input
    (``VerdictEvidence.input_alternative``) that is not also within 2 standard errors;
    min_torque_excitation [-]: smallest ratio of the logged torques' rms to the process
    noise's in the same band (``torque_excitation``). This last one was added after the
    others, and set from measured flights (docs/verdict.md: on 8 closed-loop flights of
    ``flightgen`` every inertia more than 10 % off had a ratio <= 1.47, every other >= 2.11).
    It was 2 until a 500 Hz flightgen flight (seed 6005) read I_zz 10.6 %
    high at r = 2.49 with a 1.7 % standard error. Now 3: up to 1 / r^2 of the logged
    torques' variance may be the controller's answer to the noise, which biases the
    inertia read from them; at r = 3 that is 11 %.

    The known-mass route's single numbers (``judge_estimate``): max_rel_se [-]: largest
    relative total standard error of a trusted estimate; min_fit_share [-]: smallest
    share of the (band-passed) torque or vertical-force variance the regression must
    explain; max_band_shift [-]: largest shift, in combined statistical standard errors,
    between the inertia on the torque band's lower and upper halves.
    """

    mass_factor: float = 2.0
    inertia_factor: float = 4.0
    max_range_share: float = 0.25
    min_torque_share: float = 0.25
    max_nis_ratio: float = 3.0
    max_input_shift: float = 0.05
    min_torque_excitation: float = 3.0
    max_rel_se: float = 0.10
    min_fit_share: float = 0.5
    max_band_shift: float = 2.0


DEFAULT_THRESHOLDS = VerdictThresholds()


def vehicle_range(vehicle: str, mass_guess: float | None = None,
                  inertia_guess: Array | None = None,
                  thresholds: VerdictThresholds = DEFAULT_THRESHOLDS) -> VehicleRange | None:
    """The range of a shipped vehicle (``core.params.VEHICLES``: its URDF values); of a
    vehicle file (``.toml``) its ``[reference]`` mass and inertia where it gives them,
    else its ``[body]``'s (never the guesses: EM starts there, often far off on
    purpose); for an unknown name the sidecar's guesses; None when neither is known.
    Raises VehicleFileError for an unreadable vehicle file."""
    known = VEHICLES.get(vehicle)
    if known is not None:
        mass, inertia, source = known.mass, known.inertia_diag, f"{vehicle} URDF"
    elif is_vehicle_file(vehicle):
        spec = load_vehicle(vehicle)
        ref = spec.reference
        mass = spec.mass if ref.mass is None else ref.mass
        inertia = np.diag(spec.inertia).copy() if ref.inertia is None else np.asarray(ref.inertia)
        source = (f"{spec.name} file: mass from its [{'body' if ref.mass is None else 'reference'}]"
                  f", inertia from its [{'body' if ref.inertia is None else 'reference'}]")
    elif mass_guess is not None and inertia_guess is not None:
        mass = float(mass_guess)
        inertia = np.diag(np.asarray(inertia_guess, dtype=float).reshape(3, 3)).copy()
        source = "the sidecar's guesses"
    else:
        return None
    fm, fi = thresholds.mass_factor, thresholds.inertia_factor
    return VehicleRange((mass / fm, mass * fm), inertia / fi, inertia * fi,
                        f"{source}; mass / {fm:g} to x {fm:g}, inertia / {fi:g} to x {fi:g}")


@dataclass(frozen=True)
class ExplainedShare:
    """How much of the variance a regression fits its model explains: names, the
    estimates that rest on the regression; explains, its model with the verb in words
    (e.g. ``the curve explains``); of, the fitted variance in words (e.g. ``the vertical
    force``); share [-] (1 - var(residual) / var(data))."""

    names: tuple[str, ...]
    explains: str
    of: str
    share: float


@dataclass(frozen=True)
class BandHalves:
    """One inertia read again on the lower and upper halves of the torque band: name;
    low, high (value [kg m^2], statistical standard error [kg m^2]); edges (lo, mid, hi)
    [Hz], the halves lo-mid and mid-hi. A rigid body with the right torques reads the
    same inertia on both."""

    name: str
    low: tuple[float, float]
    high: tuple[float, float]
    edges: tuple[float, float, float]


@dataclass(frozen=True)
class VerdictEvidence:
    """What the data say about an estimate, beside its standard errors.

    torque_share (3,) [-]: share of the angular-acceleration variance per body axis that
    the torques explain (NaN: not computed); torque_band: the frequencies it was measured
    on, in words; nis_ratio: channel -> mean normalised innovation squared per row [-];
    input_alternative (4,) [kg, kg m^2 x 3] or None: [m, I_xx, I_yy, I_zz] estimated
    from the same log with its sampled input read the other way (held over each
    interval instead of the mean of the interval's two rows, ``models.sources.
    interval_inputs``): a parameter that moves by more than ``max_input_shift`` and 2
    standard errors between the two rests on what the log does not record;
    torque_excitation (3,) [-]: the logged torques' rms against the process noise's per
    body axis (``torque_excitation``; NaN: not computed), on the band excitation_band
    (in words); at_bound: the names of [m, I_xx, I_yy, I_zz] that ended on the edge of
    the range EM searched (``search_range``), described by bound_source; not_converged:
    why the fit is not the likelihood's maximum (EM stopped before it converged), else
    None; model_free_mass (value, standard error) [kg] or None: the mass that balances
    the flight's mean vertical force without the dynamic model (``mass_balance``);
    input_free_stderr (4,) or None: the standard errors without the input reading's part,
    which the input alternative's shift is compared with (an error that counts the
    shift would always cover it); balance_stderr [kg] or None: the mass's standard error
    without the parts the model-free balance shares (the same thrust: its calibration,
    between-flight model error, PWM repair; ``ErrorBudget.unshared_with_thrust``), which
    the balance is compared with (None: the mass's total); reference: the vehicle's
    values known without flight data (``reference``), or None; error_failures: (name,
    reason) of each parameter whose error estimate failed (``edges.collapsed_errors``).

    The known-mass route's findings (``judge_estimate``): explained, the regressions'
    explained shares (``ExplainedShare``); band_halves, the inertia on the torque band's
    halves (``BandHalves``); undetermined: (name, reason) of each estimate the fit does
    not determine, whatever its standard error.
    """

    torque_share: Array = field(default_factory=lambda: np.full(3, np.nan))
    torque_band: str = "all frequencies"
    nis_ratio: dict[str, float] = field(default_factory=dict)
    input_alternative: Array | None = None
    torque_excitation: Array = field(default_factory=lambda: np.full(3, np.nan))
    excitation_band: str = ""
    at_bound: tuple[str, ...] = ()
    bound_source: str = ""
    not_converged: str | None = None
    model_free_mass: tuple[float, float] | None = None
    input_free_stderr: Array | None = None
    balance_stderr: float | None = None
    reference: ReferenceValues | None = None
    error_failures: tuple[tuple[str, str], ...] = ()
    explained: tuple[ExplainedShare, ...] = ()
    band_halves: tuple[BandHalves, ...] = ()
    undetermined: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True)
class Estimate:
    """One identified number with its verdict: name (``mass``, ``I_xx``, ..., ``I_xy``,
    ``thrust c_2``, ``time constant``, ...), value and total standard error stderr in
    unit (SI; NaN: not computed), parts: the total's parts by source (name, se), combined
    in quadrature (empty when the route keeps them elsewhere: a vehicle estimate's are in
    its ``ErrorBudget``), verdict (one of ``VERDICTS``) and the reasons behind it."""

    name: str
    value: float
    unit: str
    stderr: float
    parts: tuple[tuple[str, float], ...]
    verdict: str
    reasons: tuple[str, ...] = ()

    @property
    def trusted(self) -> bool:
        return self.verdict == TRUSTED

    def verdict_report(self) -> dict:
        """report.json's entry of the parameter under ``verdict.parameters``."""
        return {"verdict": self.verdict, "reasons": list(self.reasons)}


@dataclass(frozen=True)
class EstimateVerdict:
    """The verdicts of one estimate's parameters and the overall one (the most severe)."""

    parameters: tuple[Estimate, ...]
    overall: str
    reasons: tuple[str, ...]

    @property
    def trusted(self) -> bool:
        return self.overall == TRUSTED

    def get(self, name: str) -> Estimate:
        return next(p for p in self.parameters if p.name == name)

    def to_report(self) -> dict:
        """report.json's ``verdict``: overall, its reasons, one entry per parameter."""
        return {"overall": self.overall, "reasons": list(self.reasons),
                "parameters": {p.name: p.verdict_report() for p in self.parameters}}


def _worst(verdicts: Sequence[str]) -> str:
    return max(verdicts, key=VERDICTS.index) if verdicts else TRUSTED


def _range_check(name: str, se: float, lo: float, hi: float, scale: float, unit: str,
                 th: VerdictThresholds) -> list[str]:
    if not np.isfinite(se):
        return []
    share = 4.0 * se / (hi - lo)
    if share <= th.max_range_share:
        return []
    return [f"its +-2 standard errors ({se * scale:.3g} {unit} each) cover {100 * share:.1f} % "
            f"of the vehicle's range {lo * scale:.3g}-{hi * scale:.3g} {unit} "
            f"(at most {100 * th.max_range_share:.0f} %)"]


def range_reasons(index: int, stderr: float, vrange: VehicleRange,
                  thresholds: VerdictThresholds = DEFAULT_THRESHOLDS) -> list[str]:
    """The reasons (none, or one) that parameter ``index`` of [m, I_xx, I_yy, I_zz] is not
    identifiable by its standard error ``stderr`` [kg or kg m^2] alone: its +-2 standard
    errors cover more than ``max_range_share`` of the vehicle's range (``judge``'s check,
    for callers that scale an error after the verdict, ``realdata.consistency``)."""
    if index == 0:
        return _range_check("mass", stderr, *vrange.mass, 1e3, "g", thresholds)
    i = index - 1
    return _range_check(DIAGONAL[i], stderr, float(vrange.inertia_lo[i]),
                        float(vrange.inertia_hi[i]), 1e6, "e-6 kg m^2", thresholds)


def _nis_check(evidence: VerdictEvidence, channels: Sequence[str],
               th: VerdictThresholds) -> list[str]:
    bad = [(c, evidence.nis_ratio[c]) for c in channels
           if c in evidence.nis_ratio and evidence.nis_ratio[c] > th.max_nis_ratio]
    return [f"{c} innovations are {np.sqrt(r):.1f}x the size the model predicts (mean "
            f"normalised innovation squared per row {r:.2f}, at most {th.max_nis_ratio:g})"
            for c, r in bad]


def _input_check(name: str, index: int, value: float, se: float, evidence: VerdictEvidence,
                 scale: float, unit: str, th: VerdictThresholds) -> list[str]:
    if evidence.input_alternative is None:
        return []
    if evidence.input_free_stderr is not None:  # the budget's total counts the shift itself
        se = float(evidence.input_free_stderr[index])
    alt = float(evidence.input_alternative[index])
    shift = abs(value - alt)
    if shift <= th.max_input_shift * abs(value) or (np.isfinite(se) and shift <= 2.0 * se):
        return []
    return [f"rests on how the sampled input acted between rows, which the log does not "
            f"record: {alt * scale:.4g} {unit} if each row was held instead of the rows' "
            f"mean ({100 * (alt - value) / value:+.0f} %)"]


def _fit_checks(name: str, evidence: VerdictEvidence) -> list[str]:
    """Reasons the fit itself gives that parameter ``name`` is not determined: EM did not
    converge, the parameter ended on the edge of the range EM searched, or its error
    estimate failed."""
    out = [] if evidence.not_converged is None else [evidence.not_converged]
    out += [why for n, why in evidence.error_failures if n == name]
    if name in evidence.at_bound:
        out.append(f"ended on the edge of the range EM searched ({evidence.bound_source}): "
                   "the log does not determine it, the number is the edge, not a fit")
    return out


def _judged(se: float, missing_stderr: str | None) -> list[str]:
    """A number without a standard error that nobody asked for is not judged."""
    return [NO_STDERR] if not np.isfinite(se) and not missing_stderr else []


def _assemble(name: str, value: float, unit: str, se: float, parts: Sequence[tuple[str, float]],
              findings: Sequence[tuple[str, str]]) -> Estimate:
    """The estimate with its verdict: the most severe of the findings' (verdict, reason),
    trusted without any; every reason kept, in the findings' order."""
    return Estimate(name, float(value), unit, float(se), tuple(parts),
                    _worst([v for v, _ in findings]), tuple(r for _, r in findings))


def _judge(name: str, value: float, unit: str, se: float, checks: dict[str, list[str]],
           parts: Sequence[tuple[str, float]] = ()) -> Estimate:
    """A vehicle parameter's estimate from its checks (verdict -> reasons), the reasons of
    the most severe verdict first."""
    return _assemble(name, value, unit, se, parts,
                     [(v, r) for v in reversed(VERDICTS[1:]) for r in checks.get(v, [])])


def judge(mass: float, inertia: Array, stderr: Array, evidence: VerdictEvidence,
          vrange: VehicleRange | None, stderr_products: Array | None = None,
          thresholds: VerdictThresholds = DEFAULT_THRESHOLDS,
          missing_stderr: str | None = None,
          parts: Mapping[str, Array] | None = None) -> EstimateVerdict:
    """The verdict of one estimate (module docstring).

    mass [kg]; inertia (3, 3) [kg m^2]; stderr (4,) of [m, I_xx, I_yy, I_zz] (NaN: not
    computed, no identifiability check by standard error); evidence: torque shares and
    innovation consistency; vrange: the vehicle's range (None: positivity and the
    triangle inequality only); stderr_products (3,) of [I_xy, I_xz, I_yz] when the
    products of inertia were estimated (their parameters are judged too);
    missing_stderr: the standard errors were asked for, and a NaN one is then "not
    identifiable" for this reason (a number without its uncertainty is not trusted);
    parts: stderr by source, name -> (4,) (an ``ErrorBudget``'s), kept on each of
    [m, I_xx, I_yy, I_zz]'s ``Estimate``.
    """
    th = thresholds
    inertia = np.asarray(inertia, dtype=float).reshape(3, 3)
    stderr = np.asarray(stderr, dtype=float)
    diag = np.diag(inertia)
    params: list[Estimate] = []

    def parts_of(index: int) -> tuple[tuple[str, float], ...]:
        return tuple((k, float(np.asarray(v)[index])) for k, v in (parts or {}).items())

    # mass
    bad_value: list[str] = []
    if not mass > 0:
        bad_value.append(f"mass {mass * 1e3:.4g} g is not positive")
    elif vrange is not None and not vrange.mass[0] <= mass <= vrange.mass[1]:
        bad_value.append(f"mass {mass * 1e3:.4g} g outside the vehicle's "
                         f"{vrange.mass[0] * 1e3:.4g}-{vrange.mass[1] * 1e3:.4g} g "
                         f"({vrange.source})")
    ident = [] if vrange is None else _range_check("mass", stderr[0], *vrange.mass, 1e3, "g", th)
    ident += _input_check("mass", 0, mass, stderr[0], evidence, 1e3, "g", th)
    ident += _fit_checks("mass", evidence)
    if missing_stderr and not np.isfinite(stderr[0]):
        ident.append(missing_stderr)
    params.append(_judge("mass", mass, "kg", stderr[0], {
        NOT_IDENTIFIABLE: ident,
        NOT_ADEQUATE: _nis_check(evidence, MASS_CHANNELS, th)
        + balance_check(mass, stderr[0], evidence.model_free_mass, evidence.balance_stderr)
        + reference_check("mass", 0, mass, stderr[0], evidence.reference, 1e3, "g"),
        IMPLAUSIBLE: bad_value, NOT_JUDGED: _judged(stderr[0], missing_stderr)}, parts_of(0)))

    # the tensor as a whole: positive definite, principal moments obey the triangle inequality
    tensor: list[str] = []
    sym = 0.5 * (inertia + inertia.T)
    principal = np.linalg.eigvalsh(sym)
    if principal[0] <= 0:
        tensor.append(f"inertia tensor not positive definite (principal moments "
                      f"{', '.join(f'{v * 1e6:.4g}' for v in principal)} e-6 kg m^2)")
    elif principal[0] + principal[1] < principal[2]:
        tensor.append(f"principal moments break the triangle inequality: "
                      f"{principal[0] * 1e6:.4g} + {principal[1] * 1e6:.4g} < "
                      f"{principal[2] * 1e6:.4g} e-6 kg m^2")
    face = triangle_face(inertia)  # a face of the set EM searched: held there, not fitted
    rotation = _nis_check(evidence, INERTIA_CHANNELS, th)
    rotation_ref = vehicle_mismatch(mass, stderr[0], evidence.reference)
    share = np.asarray(evidence.torque_share, dtype=float)
    excitation = np.asarray(evidence.torque_excitation, dtype=float)
    for i, name in enumerate(DIAGONAL):
        value = float(diag[i])
        implausible = list(tensor)
        if vrange is not None and not vrange.inertia_lo[i] <= value <= vrange.inertia_hi[i]:
            implausible.append(
                f"{name} {value * 1e6:.4g} e-6 kg m^2 outside the vehicle's "
                f"{vrange.inertia_lo[i] * 1e6:.4g}-{vrange.inertia_hi[i] * 1e6:.4g} e-6 kg m^2 "
                f"({vrange.source})")
        ident = [] if vrange is None else _range_check(
            name, stderr[i + 1], vrange.inertia_lo[i], vrange.inertia_hi[i], 1e6, "e-6 kg m^2", th)
        ident += _input_check(name, i + 1, value, stderr[i + 1], evidence, 1e6, "e-6 kg m^2", th)
        ident += ([] if face is None else [face]) + _fit_checks(name, evidence)  # the cause first
        if missing_stderr and not np.isfinite(stderr[i + 1]):
            ident.append(missing_stderr)
        if np.isfinite(excitation[i]) and excitation[i] < th.min_torque_excitation:
            ident.insert(0, f"the logged torques about body {name[-1]} are {excitation[i]:.2f}x "
                            f"the size of the process noise's ({evidence.excitation_band}; at "
                            f"least {th.min_torque_excitation:g}x needed): torques no larger "
                            f"than the unrecorded disturbances, such as a fast controller's "
                            f"answers to them, do not carry the inertia")
        if np.isfinite(share[i]) and share[i] < th.min_torque_share:
            ident.insert(0, f"torques explain {100 * share[i]:.0f} % of the angular "
                            f"acceleration about body {name[-1]} ({evidence.torque_band}; at "
                            f"least {100 * th.min_torque_share:.0f} % needed)")
        params.append(_judge(name, value, "kg m^2", stderr[i + 1], {
            NOT_IDENTIFIABLE: ident, IMPLAUSIBLE: implausible,
            NOT_ADEQUATE: rotation + rotation_ref + reference_check(
                name, i + 1, value, stderr[i + 1], evidence.reference, 1e6, "e-6 kg m^2"),
            NOT_JUDGED: _judged(stderr[i + 1], missing_stderr)}, parts_of(i + 1)))
    if stderr_products is not None:
        for (name, i, j), se in zip(PRODUCTS, np.asarray(stderr_products, dtype=float),
                                    strict=True):
            k = 3 - i - j
            ident = []
            if vrange is not None:  # |I_ij| <= I_kk / 2 for any rigid body
                half = 0.5 * vrange.inertia_hi[k]
                ident = _range_check(name, se, -half, half, 1e6, "e-6 kg m^2", th)
            ident += ([] if face is None else [face]) + _fit_checks(name, evidence)  # the cause first
            quiet = [a for a in (i, j) if np.isfinite(excitation[a])
                     and excitation[a] < th.min_torque_excitation]
            if quiet:
                ident.insert(0, f"the logged torques about a body axis it couples are "
                                f"{min(excitation[a] for a in quiet):.2f}x the size of the "
                                f"process noise's")
            low = [a for a in (i, j) if np.isfinite(share[a]) and share[a] < th.min_torque_share]
            if low:
                ident.insert(0, f"torques explain {100 * min(share[a] for a in low):.0f} % of "
                                f"the angular acceleration about a body axis it couples")
            params.append(_judge(name, inertia[i, j], "kg m^2", se, {
                NOT_IDENTIFIABLE: ident, NOT_ADEQUATE: rotation, IMPLAUSIBLE: list(tensor)}))
    overall = _worst([p.verdict for p in params])
    reasons = tuple(f"{p.name}: {r}" for p in params if not p.trusted for r in p.reasons)
    return EstimateVerdict(tuple(params), overall, reasons)


def judge_estimate(name: str, value: float, unit: str, parts: Mapping[str, float],
                   evidence: VerdictEvidence | None = None,
                   thresholds: VerdictThresholds = DEFAULT_THRESHOLDS,
                   part_of: EstimateVerdict | None = None) -> Estimate:
    """One number of the known-mass route with its verdict (module docstring): value in
    unit; parts: its standard error by source (name -> se, same unit), the total their
    quadrature sum (NaN without parts). From the evidence (None: none): EM did not converge
    (``not_converged``), the regression's explained share (``explained``) and the band
    halves (``band_halves``) of this estimate, the fit does not determine it
    (``undetermined``); a moment of inertia (``DIAGONAL``) must be positive; part_of: the
    verdict of the vehicle estimate (``judge``) the number is part of, whose reasons on it
    count with its verdict. Then its total standard error must be at most ``max_rel_se``
    of its value; a number without a value (NaN) is not identifiable. Reasons in that
    order; the verdict is the most severe."""
    th = thresholds
    evidence = VerdictEvidence() if evidence is None else evidence
    total = math.sqrt(sum(v * v for v in parts.values())) if parts else math.nan
    findings: list[tuple[str, str]] = []
    if evidence.not_converged is not None:
        findings.append((NOT_IDENTIFIABLE, evidence.not_converged))
    findings += [(NOT_ADEQUATE, f"{e.explains} {e.share * 100:.0f} % of {e.of} (at least "
                                f"{th.min_fit_share * 100:.0f} % demanded)")
                 for e in evidence.explained if name in e.names and e.share < th.min_fit_share]
    for h in evidence.band_halves:
        shift, combined = abs(h.low[0] - h.high[0]), math.hypot(h.low[1], h.high[1])
        if h.name == name and shift > th.max_band_shift * combined:
            lo, mid, hi = h.edges
            findings.append((NOT_ADEQUATE, (
                f"{name}: {h.low[0]:.4g} on {lo:g}-{mid:.2g} Hz but {h.high[0]:.4g} on "
                f"{mid:.2g}-{hi:g} Hz, {shift / combined:.1f} statistical errors apart: the "
                "torque model is wrong in a frequency-dependent way (motor dynamics, drag "
                "moments)")))
    findings += [(NOT_IDENTIFIABLE, why) for n, why in evidence.undetermined if n == name]
    if name in DIAGONAL and value <= 0.0:
        findings.append((IMPLAUSIBLE, f"{name}: {value:.3g} is not positive"))
    if part_of is not None and any(p.name == name for p in part_of.parameters):
        house = part_of.get(name)
        findings += [(house.verdict, r) for r in house.reasons]
    if not math.isfinite(value):
        if not findings:
            findings.append((NOT_IDENTIFIABLE, f"{name}: the fit gave no value"))
    elif not (math.isfinite(total) and abs(total) <= th.max_rel_se * abs(value)):
        share = f"{abs(total / value) * 100:.0f} %" if value != 0 else "unbounded share"
        big = max(parts.items(), key=lambda kv: kv[1] if math.isfinite(kv[1]) else math.inf,
                  default=None)
        largest = f"; largest part: {big[0]} {big[1]:.3g}" if big and len(parts) > 1 else ""
        findings.append((NOT_IDENTIFIABLE, (
            f"{name}: total standard error {total:.3g} is {share} of the value {value:.3g} "
            f"(trusted at most {th.max_rel_se * 100:.0f} %{largest})")))
    return _assemble(name, value, unit, total, tuple(parts.items()), findings)


def scaled_error_verdicts(verdicts: Mapping[str, str], overall: str, totals: Array,
                          scale: Array, vrange: VehicleRange | None,
                          thresholds: VerdictThresholds = DEFAULT_THRESHOLDS
                          ) -> tuple[dict[str, str], str]:
    """A report's verdicts (name -> verdict of mass, I_xx, I_yy, I_zz; the overall one)
    after the scatter between flights scaled its errors by scale (4,) [-] to totals (4,)
    [kg, kg m^2]: a trusted parameter whose error grew (scale > 1) until it covers too
    much of the vehicle's range (``range_reasons``) is not identifiable, and so is a
    trusted overall verdict with such a parameter. Only that check depends on the error's
    size, so a verdict can only be lowered; without a range nothing changes."""
    out = dict(verdicts)
    for j, name in enumerate(("mass", *DIAGONAL)):
        if out.get(name) == TRUSTED and vrange is not None and scale[j] > 1.0 \
                and range_reasons(j, float(totals[j]), vrange, thresholds):
            out[name] = NOT_IDENTIFIABLE
    lowered = out != dict(verdicts)
    return out, NOT_IDENTIFIABLE if lowered and overall == TRUSTED else overall
