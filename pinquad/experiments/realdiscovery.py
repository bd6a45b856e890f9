"""Effect discovery on the measured Crazyflie flights, trained on some logs and tested on others.

``python -m pinquad.realdiscovery [--data DIR]``:

1. every flight of the split is identified as ``offline --log`` does (``realdata``:
   100 Hz observations, band-limited inertia M-step with the nuisance air-speed moment)
   and discovery (``pinquad.discovery.discover.discover.discover``, effects fitted on the base posterior)
   is run on it alone: what each flight names by itself;
2. the effects named by at least half of the training flights are fitted on all training
   flights together (profiled ML of ``pinquad.discovery.discover``: summed expected Gram
   matrices, mass and inertia re-fitted with the effects' coefficients, the wrench row
   variances profiled out); standard errors by leave-one-flight-out jackknife;
3. on each test flight (never used in step 2) the wrench residual of its own smoothed
   trajectory is evaluated with the training base model (pi_0) and with the training
   base model + effects (pi_1, c): RMS per axis of 0.1-s means, before -> after.

Splits (``SPLITS``): ``drag`` trains on the fast figure-8s and tests on the other
figure-8 controller and the circle; ``ground`` trains on low random flights and tests on
other random flights, jana28 the other one that passes below 8 cm (motor 1's faulty RPM
rebuilt from PWM by ``realdata``); ``lowest`` turns that round: it holds out jana20, the
flight with the most time near the floor (1.9 s below 12 cm), and trains on the other
four random flights, which spend little time there (jana28 0.5 s).
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pinquad.io.datadir import default_data_dir

Array = NDArray[np.float64]

SPLITS: dict[str, tuple[tuple[str, ...], tuple[str, ...], str]] = {
    "drag": (("jana00", "jana02"), ("jana03", "jana10"), "drag"),
    "ground": (("jana20", "jana23", "jana24"), ("jana28", "jana25"), "ground_effect"),
    "lowest": (("jana23", "jana24", "jana25", "jana28"), ("jana20",), "ground_effect"),
}
"""Split name -> (training logs, test logs in imrc_brushed/, the effect the split is
about: also fitted and tested alone, whether or not the training flights named it)."""

POOLED = ("drag", "ground_effect", "com_offset", "wind")
"""Effects the pooled cross-flight fit handles (linear wrench effects)."""


@dataclass(frozen=True)
class FlightFit:
    """One measured flight after base EM and its own discovery."""

    name: str
    obs: object
    theta: object
    posterior: object
    selected: tuple[str, ...]
    section: dict
    mass: float
    inertia: Array
    min_height: float
    max_speed: float


def fit_flight(path: Path, max_iterations: int = 60) -> FlightFit:
    """Base identification (``realdata.identify_real``) and discovery of one log."""
    from pinquad.discovery.discover import DiscoveryConfig, discover
    from pinquad.experiments.logmode import _plain_theta
    from pinquad.io.sdlog import read_sdflight
    from pinquad.realdata.flights import (
        build_observations,
        corrected,
        default_guess,
        identify_real,
        raw_from_sdflight,
    )

    raw = raw_from_sdflight(read_sdflight(path))
    real = build_observations(raw)
    mass0, inertia0, _ = default_guess("crazyflie21")
    ident, post, theta = identify_real(real, mass0, inertia0, max_iterations, False, name=path.name)
    obs = corrected(real.obs, theta)
    plain = _plain_theta(theta)
    out = discover(obs, plain, post, cfg=DiscoveryConfig(refit_em=False))
    speed = np.linalg.norm(post.mean[:, 3:6], axis=1)
    flying = post.mean[:, 2] > 0.03
    return FlightFit(path.name, obs, plain, post, out.selected, out.to_report(), ident.mass,
                     ident.inertia, float(np.min(post.mean[flying, 2])) if flying.any() else 0.0,
                     float(np.max(speed)))


def _gram(fit: FlightFit, effects: tuple[str, ...]) -> tuple[Array, int]:
    from pinquad.discovery.discover import _effect_columns, _grams, _residuals

    res = _residuals(fit.obs, fit.posterior, fit.theta.gravity, 2.0)
    phi, fixed = _effect_columns(res, list(effects), None)
    return _grams(res, phi, fixed).sum(axis=0), int(res.idx.size)


def pooled_fit(fits: list[FlightFit], effects: tuple[str, ...]):
    """Profiled ML of (pi, c) on all flights in ``fits`` together (module docstring)."""
    from pinquad.discovery.discover import _fit
    from pinquad.discovery.library import SPECS

    grams = [_gram(f, effects) for f in fits]
    g = sum(gr for gr, _ in grams)
    n = sum(k for _, k in grams)
    pi0 = np.r_[np.mean([f.mass for f in fits]), np.mean([f.inertia for f in fits], axis=0)]
    p = sum(SPECS[e].n_coefficients for e in effects)
    return _fit(g, n, pi0, p)


def _split_coefficients(c: Array, effects: tuple[str, ...]) -> dict[str, Array]:
    from pinquad.discovery.library import SPECS

    out, j = {}, 0
    for e in effects:
        k = SPECS[e].n_coefficients
        out[e] = c[j:j + k]
        j += k
    return out


NEAR_FLOOR_M = 0.12
"""Height [m] below which a step counts as near the floor (ground effect's gain there is
at least (0.046 / 0.48)^2 = 0.9 % per unit k_ge)."""


def near_floor(fit: FlightFit) -> NDArray[np.bool_]:
    """(N,) used transitions k (not excluded: no ground contact, take-off or landing)
    whose smoothed height is below ``NEAR_FLOOR_M``."""
    n = fit.obs.n
    used = np.zeros(n, dtype=bool)
    used[: n - 1] = ~np.asarray(fit.obs.exclude[: n - 1], dtype=bool) \
        if fit.obs.exclude.size else True
    return used & (fit.posterior.mean[:, 2] < NEAR_FLOOR_M)


def evaluate(fit: FlightFit, pi: Array, coeffs: dict[str, Array],
             steps_mask: NDArray[np.bool_] | None = None) -> dict[str, float]:
    """RMS per axis of 0.1-s means of the test flight's wrench residual (whole flight, or
    the steps in ``steps_mask``)."""
    from pinquad.discovery.discover import _heldout_rms, _residuals

    res = _residuals(fit.obs, fit.posterior, fit.theta.gravity, 2.0)
    window = max(int(round(0.1 / fit.obs.dt)), 1)
    return _heldout_rms(res, pi, coeffs, np.ones(res.n_blocks, dtype=bool), window, steps_mask)


def run_split(name: str, data: Path, cache: dict[str, FlightFit]) -> dict:
    """Train / test one split; returns its table entries."""
    train_names, test_names, target = SPLITS[name]
    for n in (*train_names, *test_names):
        if n not in cache:
            path = data / n
            if not path.is_file():
                raise FileNotFoundError(f"{path}: flight log not found (expected the shared "
                                        "Crazyflie data, imrc_brushed/)")
            cache[n] = fit_flight(path)
    train = [cache[n] for n in train_names]
    test = [cache[n] for n in test_names]
    votes = {e: sum(e in f.selected for f in train) for e in POOLED}
    effects = tuple(e for e in POOLED if 2 * votes[e] >= len(train) and votes[e] > 0)
    base = pooled_fit(train, ())
    entry: dict = {"train": list(train_names), "test": list(test_names),
                   "named_by_flight": {f.name: list(f.selected) for f in [*train, *test]},
                   "flights": {f.name: [f.min_height, f.max_speed] for f in [*train, *test]},
                   "pooled_effects": list(effects), "votes": votes,
                   "base": {"mass": float(base.pi[0]), "inertia_diag": base.pi[1:].tolist()}}
    if effects:
        ext = pooled_fit(train, effects)
        coeffs = _split_coefficients(ext.c, effects)
        draws = [pooled_fit([f for f in train if f is not g], effects).c for g in train] \
            if len(train) >= 2 else []
        se = (np.sqrt((len(train) - 1) / len(train)
                      * np.sum((np.array(draws) - np.mean(draws, axis=0)) ** 2, axis=0))
              if draws else np.full(ext.c.size, np.nan))
        entry["coefficients"] = {e: v.tolist() for e, v in coeffs.items()}
        entry["stderr_leave_one_flight_out"] = {e: v.tolist() for e, v in
                                                _split_coefficients(se, effects).items()}
        entry["refit"] = {"mass": float(ext.pi[0]), "inertia_diag": ext.pi[1:].tolist()}
        pi1 = ext.pi
    else:
        coeffs, pi1 = {}, base.pi
    alone = pooled_fit(train, (target,))
    alone_coeffs = _split_coefficients(alone.c, (target,))
    entry["target"] = {"effect": target, "coefficients": alone.c.tolist(),
                       "test_rms": {f.name: {"before": evaluate(f, base.pi, {}),
                                             "after": evaluate(f, alone.pi, alone_coeffs)}
                                    for f in test}}
    if target == "ground_effect":
        # the whole-flight RMS dilutes a force that acts only near the floor
        entry["target"]["near_floor"] = {
            f.name: {"seconds": float(near_floor(f).sum() * f.obs.dt),
                     "before": evaluate(f, base.pi, {}, near_floor(f)),
                     "after": evaluate(f, alone.pi, alone_coeffs, near_floor(f))}
            for f in test}
    entry["test_rms"] = {}
    for f in test:
        before = evaluate(f, base.pi, {})
        after = evaluate(f, pi1, coeffs)
        entry["test_rms"][f.name] = {"before": before, "after": after,
                                     "min_height_m": f.min_height, "max_speed_m_s": f.max_speed}
    return entry


def table(results: dict) -> str:
    """Markdown: per split the effects, coefficients and the test flights' before/after."""
    from pinquad.discovery.library import SPECS

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


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m pinquad.realdiscovery",
                                description="Effect discovery on the measured Crazyflie flights: "
                                            "train on some logs, test on others.")
    p.add_argument("--data", type=Path, default=None,
                   help="imrc_brushed/ directory (default: ../shared/data/crazyflie/imrc_brushed "
                        "next to the repository)")
    p.add_argument("--splits", nargs="*", default=list(SPLITS), choices=list(SPLITS))
    p.add_argument("--out", type=Path, default=None, help="write realdiscovery.json/.md here")
    args = p.parse_args(argv)
    data = args.data or default_data_dir() / "imrc_brushed"
    if (data / "imrc_brushed").is_dir():
        data = data / "imrc_brushed"
    if not data.is_dir():
        print(f"error: {data}: no such directory; expected the Crazyflie flight logs "
              "(imrc_brushed/)", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    cache: dict[str, FlightFit] = {}
    results = {}
    try:
        for s in args.splits:
            print(f"split {s}: train {', '.join(SPLITS[s][0])}; test {', '.join(SPLITS[s][1])}; "
                  f"effect {SPLITS[s][2]}",
                  flush=True)
            results[s] = run_split(s, data, cache)
    except (FileNotFoundError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    text = table(results)
    print(text)
    for s, r in results.items():
        if "refit" in r:
            print(f"{s}: training mass {1e3 * r['base']['mass']:.2f} g -> {1e3 * r['refit']['mass']:.2f} g "
                  f"with {', '.join(r['pooled_effects'])}")
    print(f"{time.perf_counter() - t0:.0f} s")
    if args.out is not None:
        from pinquad.io.runs import atomic_write_json

        args.out.mkdir(parents=True, exist_ok=True)
        atomic_write_json(args.out / "realdiscovery.json", results)
        (args.out / "realdiscovery.md").write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
