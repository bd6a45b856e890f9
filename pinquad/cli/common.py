"""What the command lines share: the check of ``--out`` before any work
(``output_problem``), the execution backend's options (``--jobs``, ``--scheduler``,
``--cluster``: ``add_backend_arguments``), the online commands'
``--memory`` value and its description, the one-paragraph message of an exit-2 failure
that names the log (``failure_message``; the measured-flight diagnostics' log arguments
are in ``pinquad.cli.measured``)."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from pinquad.cli.help import positive_int
from pinquad.core.execution import INSTALL_HINT, Backend, BackendError, parse_cluster_spec
from pinquad.io.runs import OutputError, check_output_directory, check_output_file


def memory_arg(text: str) -> float | None:
    """The online commands' --memory: a positive number of seconds, inf, or none."""
    if text.strip().lower() == "none":
        return None
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected seconds (> 0), inf or none, got {text!r}") from None
    if not value > 0.0:
        raise argparse.ArgumentTypeError(f"expected seconds (> 0), inf or none, got {text!r}")
    return value


def output_problem(path: Path | None, directory: bool) -> int | None:
    """Check ``--out`` before any work (``pinquad.io.runs``): None when it can be written
    (or is not given), else print a located error and return exit code 2."""
    if path is None:
        return None
    try:
        (check_output_directory if directory else check_output_file)(path)
    except OutputError as exc:
        print(f"error: --out {exc}", file=sys.stderr)
        return 2
    return None


def memory_label(memory_s: float | None) -> str:
    """How the online M-step remembers samples that left the window, in words."""
    if memory_s is None:
        return "window only"
    if math.isinf(memory_s):
        return "every airborne sample (incremental EM)"
    return f"forgotten with time constant {memory_s:g} s"



def cluster_arg(text: str) -> int:
    """``--cluster local:N``: N, else argparse's type error (exit 2, the expected form)."""
    try:
        return parse_cluster_spec(text)
    except BackendError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("--cluster ")) from None


def add_backend_arguments(parser: argparse.ArgumentParser, jobs_default: int,
                          tasks: str) -> None:
    """The execution backend's options (``pinquad.core.execution``), the same on every
    command that runs many tasks: ``--jobs`` for the local process pool, or ``--scheduler``
    / ``--cluster`` for a Dask cluster. ``tasks`` names what is run in parallel."""
    parser.add_argument("--jobs", type=positive_int, default=jobs_default,
                        help=f"worker processes of the local process pool for the {tasks} "
                             "(1: in this process)")
    dask = parser.add_mutually_exclusive_group()
    dask.add_argument("--scheduler", metavar="ADDRESS", default=None,
                      help=f"run the {tasks} on an existing Dask cluster whose scheduler is at "
                           "ADDRESS (tcp://HOST:PORT; its workers must see the same files), "
                           "instead of the process pool; the same tasks and seeds, the same "
                           f"numbers (needs {INSTALL_HINT})")
    dask.add_argument("--cluster", type=cluster_arg, metavar="local:N", default=None,
                      help=f"run the {tasks} on a local Dask cluster of N single-threaded "
                           "worker processes started for this run, instead of the process "
                           f"pool; the same numbers (needs {INSTALL_HINT})")


def backend_from_args(args: argparse.Namespace) -> Backend:
    """The Backend that ``add_backend_arguments``' options name."""
    return Backend(jobs=args.jobs, scheduler=args.scheduler, cluster_workers=args.cluster)


def check_band(parser: argparse.ArgumentParser, band: Sequence[float] | None) -> None:
    """Exit 2 through ``parser.error`` unless ``band`` (``--band LO HI`` [Hz]) has
    0 <= LO < HI (LO = 0: the torque rows are low-pass filtered only)."""
    if band is not None and not 0.0 <= band[0] < band[1]:
        parser.error(f"--band LO HI: expected 0 <= LO < HI [Hz] (LO = 0: low-pass only); "
                     f"got {band[0]:g} {band[1]:g}")


def failure_message(exc: BaseException, path: object | None = None) -> str:
    """The one-paragraph message of an exit-2 failure that names ``path`` (the log, or
    None when no file is involved): the exception's text on one line, prefixed with the
    path unless it names it already; a numerical failure of the fit (numpy's
    LinAlgError, FloatingPointError) says what it means for the log and what to check."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    if isinstance(exc, (np.linalg.LinAlgError, FloatingPointError)):
        text = (f"the fit failed numerically ({text}): the log's actuation and measurements "
                "do not fit a rigid-body model from the initial guess; check the rotor "
                "numbering and spin directions (--vehicle FILE), the units of each column, "
                "and the sidecar's mass_guess / inertia_guess")
    if path is not None and str(path) not in text:
        text = f"{path}: {text}"
    return text
