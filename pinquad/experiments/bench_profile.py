"""``python -m pinquad.bench --profile``: where our compiled E-step's time goes.

The stage timings call the compiled E-step's passes (``fast_smoother.prepare``,
``filter_arrays``, ``posterior_arrays`` and ``estep.passes.forward_into`` /
``backward_into``) exactly as ``smooth_quad`` calls them; if they fail, the stages are
reported unavailable (``stages_error``) and the rest of the profile stands.
"""

from __future__ import annotations

import cProfile
import gc
import io
import pstats
import resource
import time
from pathlib import Path
from typing import Any

import numpy as np

from pinquad.estep import fast_smoother as fs
from pinquad.estep.passes import backward_into, forward_into
from pinquad.experiments.bench import median
from pinquad.experiments.bench_cases import load_case


def profile_estep(case_path: Path, runs: int = 5) -> dict:
    """Where ``smooth_quad``'s time goes on one case: cProfile of the whole call, and
    stage timings (medians of ``runs``) of the wrapper's model checks and the two
    compiled passes (called directly), all in this process."""
    case = load_case(case_path)
    model, ys = case.model, np.ascontiguousarray(case.ys)
    fs.smooth_quad(model, ys)
    prof = cProfile.Profile()
    for _ in range(runs):
        prof.enable()
        fs.smooth_quad(model, ys)
        prof.disable()
    buf = io.StringIO()
    stats = pstats.Stats(prof, stream=buf)
    stats.sort_stats("tottime").print_stats(12)
    top = []
    for (file, line, func), (_, ncalls, tottime, cumtime, _) in sorted(
            stats.stats.items(), key=lambda kv: -kv[1][2])[:12]:
        top.append({"function": f"{Path(file).name}:{line}({func})", "calls": ncalls,
                    "tottime_s": tottime / runs, "cumtime_s": cumtime / runs})
    out: dict[str, Any] = {"N": case.n_steps, "runs": runs, "cprofile_top": top,
                           "cprofile_text": buf.getvalue()}
    total, faults, kernel, user = [], [], [], []
    for _ in range(runs):
        gc.collect()
        r0 = resource.getrusage(resource.RUSAGE_SELF)
        t0 = time.perf_counter()
        fs.smooth_quad(model, ys)
        total.append(time.perf_counter() - t0)
        r1 = resource.getrusage(resource.RUSAGE_SELF)
        faults.append(r1.ru_minflt - r0.ru_minflt)
        kernel.append(r1.ru_stime - r0.ru_stime)
        user.append(r1.ru_utime - r0.ru_utime)
    out["total_s"] = median(total)
    # fresh output arrays (means, covariances, cross-covariances, filter intermediates)
    # are paid for in page faults: kernel time, not arithmetic
    out["page_faults_per_call"] = median(faults)
    out["kernel_s"] = median(kernel)
    out["user_s"] = median(user)
    try:
        # the same calls, on the same arrays, as smooth_quad makes (the forward pass's
        # workspace is reused between calls; the posterior's arrays are fresh each call)
        stages: dict[str, list[float]] = {"checks": [], "forward": [], "backward": [],
                                          "output arrays": []}
        for _ in range(runs):
            gc.collect()
            t0 = time.perf_counter()
            prep = fs.prepare(model, ys)
            if prep is None:
                raise ValueError("the compiled kernels do not cover this model")
            t1 = time.perf_counter()
            fwd = fs.filter_arrays(prep.ys.shape[0])
            forward_into(prep.desc, prep.x0, prep.p0, prep.ys, True, fwd)
            t2 = time.perf_counter()
            post = fs.posterior_arrays(prep.ys.shape[0])
            t3 = time.perf_counter()
            backward_into(fwd, post)
            t4 = time.perf_counter()
            stages["checks"].append(t1 - t0)
            stages["forward"].append(t2 - t1)
            stages["output arrays"].append(t3 - t2)
            stages["backward"].append(t4 - t3)
            del post
        out["stages_s"] = {k: median(v) for k, v in stages.items()}
        other = out["total_s"] - sum(out["stages_s"].values())
        out["stages_s"]["rest (median total - stages)"] = other
    except (AttributeError, TypeError, ValueError) as exc:
        out["stages_error"] = f"stage timings unavailable ({type(exc).__name__}: {exc})"
    return out
