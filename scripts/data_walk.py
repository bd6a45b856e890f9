"""The data walk of ``pinquad.discover``: which modules ("rooms") a short log's
discovery passes through, how often it climbs back up the layers, and how often it
returns to a room it has left.

    PYTHONPATH=. python scripts/data_walk.py            # a 10 s simulated sensor-B flight
    PYTHONPATH=. python scripts/data_walk.py --list     # and the walk itself

The log is identified first (``pinquad.identify``, not recorded); then
``pinquad.discover(log, fit)`` runs under ``sys.setprofile``, which records every call
of a Python function of pinquad or estimators. A room is the module a function is
defined in. The walk is the sequence of rooms the calls enter, consecutive repeats
merged (a call inside the same module is no step). Counted:

- rooms: distinct modules on the walk;
- climbs: distinct steps (from-room -> to-room) whose destination is in a higher
  layer than their origin (the layers of ``pyproject.toml``'s import-linter contract;
  ``estimators`` below ``pinquad.core``; a module in no layer, such as ``pinquad.api``
  before it had one, at the top);
- returns: distinct steps into a room already visited and left earlier on the walk.

Distinct steps, not every step: EM loops repeat the same steps hundreds of times.
"""

from __future__ import annotations

import itertools
import sys
import time
import tomllib
from pathlib import Path

import pinquad


def layer_ranks(pyproject: Path) -> list[tuple[str, int]]:
    """(module prefix, rank) from the layers contract; rank 0 is the lowest layer."""
    config = tomllib.loads(pyproject.read_text())
    contracts = config["tool"]["importlinter"]["contracts"]
    layers = next(c["layers"] for c in contracts if c["type"] == "layers")
    ranks = [("estimators", 0)]
    for i, line in enumerate(reversed(layers)):
        ranks += [(name.strip(), i + 1) for name in line.split("|")]
    return ranks


def rank_of(module: str, ranks: list[tuple[str, int]]) -> int:
    """The layer rank of ``module`` (longest matching prefix; none: above every layer)."""
    best, rank = "", 1 + max(r for _, r in ranks)
    for prefix, r in ranks:
        if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > len(best):
            best, rank = prefix, r
    return rank


def record_walk(fn, *args) -> list[str]:
    """The rooms entered by ``fn(*args)``'s calls, consecutive repeats merged."""
    walk: list[str] = []

    def profile(frame, event, arg):
        if event != "call":
            return
        module = frame.f_globals.get("__name__", "")
        if not (module.startswith("pinquad") or module.startswith("estimators")):
            return
        if not walk or walk[-1] != module:
            walk.append(module)

    sys.setprofile(profile)
    try:
        fn(*args)
    finally:
        sys.setprofile(None)
    return walk


def counts(walk: list[str], ranks: list[tuple[str, int]]) -> tuple[int, int, int]:
    """(rooms, climbs, returns) of a walk (module docstring)."""
    steps = list(itertools.pairwise(walk))
    climbs = {(a, b) for a, b in steps if rank_of(b, ranks) > rank_of(a, ranks)}
    seen: set[str] = {walk[0]} if walk else set()
    returns = set()
    for a, b in steps:
        if b in seen:
            returns.add((a, b))
        seen.add(b)
    return len(set(walk)), len(climbs), len(returns)


def main() -> int:
    root = Path(pinquad.__file__).resolve().parents[1]
    ranks = layer_ranks(root / "pyproject.toml")
    log = pinquad.simulate(sensor="B", seed=0).slice(0, 1000)
    fit = pinquad.identify(log, information=False)
    t0 = time.perf_counter()
    walk = record_walk(pinquad.discover, log, fit)
    rooms, climbs, returns = counts(walk, ranks)
    print(f"pinquad.discover on a 10 s simulated sensor-B flight ({root}): {rooms} rooms, "
          f"{climbs} climbs back up, {returns} returns to a room already left "
          f"({len(walk)} steps; {time.perf_counter() - t0:.0f} s)")
    if "--list" in sys.argv[1:]:
        for module in dict.fromkeys(walk):
            print(f"  {rank_of(module, ranks):2d} {module}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
