"""The printed tables of ``python -m pinquad.bench`` (:func:`format_report`, from the
result document of :func:`pinquad.experiments.bench_run.run_benchmark`) and of its
``--check N`` (:func:`format_checks`)."""

from __future__ import annotations

import math

from pinquad.experiments.bench import EM_SECONDS, LARGE_N
from pinquad.experiments.bench_cases import TOLERANCE
from pinquad.experiments.bench_estep import CONTESTANTS, CheckResult


def _fmt_s(t: float | None) -> str:
    """A time ``t`` [s] in us, ms or s; "-" for none."""
    if t is None:
        return "-"
    if t < 1e-3:
        return f"{t * 1e6:.0f} us"
    if t < 1.0:
        return f"{t * 1e3:.1f} ms"
    return f"{t:.2f} s"


def _fmt(x: float | None, spec: str = ".2f", suffix: str = "") -> str:
    """``x`` formatted by ``spec`` with ``suffix``; "-" for none."""
    return "-" if x is None else f"{x:{spec}}{suffix}"


def format_report(res: dict) -> str:
    """The printed tables of a benchmark result ``res`` (times in s, us, ms as they
    come; memory in MB)."""
    lines = []
    s = res["settings"]
    m = res["machine"]
    lines.append(f"pinquad benchmark  ({m['cpu_count']} CPUs, {m.get('cpu_model', '')}, "
                 f"Python {m['python']}, numpy {m['versions'].get('numpy')}; load average "
                 f"at start {m['loadavg_at_start'][0]:.2f}, at end "
                 f"{m.get('loadavg_at_end', [math.nan])[0]:.2f})")
    lines.append(f"medians of {s['repeats']} runs ({s['repeats_large']} at N >= "
                 f"{LARGE_N:,}); peer time-out {s['timeout_s']:.0f} s")
    es = res.get("estep")
    if es:
        ns = es["N"]
        names = list(es["status"])
        lines.append("")
        lines.append("E-step: EKF + RTS smoother (with cross-covariances), wall time")
        head = f"{'method':<30}" + "".join(f"{'N=' + format(n, ','):>14}" for n in ns)
        head += f"{'slope':>8}  check vs ours"
        lines.append(head)
        for name in names:
            row = f"{CONTESTANTS[name].label:<30}"
            for i in range(len(ns)):
                st = es["status"][name][i]
                t = es[f"{name}_s"][i]
                row += f"{_fmt_s(t) if st == 'ok' else st:>14}"
            row += f"{_fmt(es['exponent'].get(name)):>8}"
            if name != "ours":
                errs = [e for e in es["check_error"][name] if e is not None]
                row += f"  {max(errs):.0e}" if errs else "  -"
            lines.append(row)
        if "dynamax_compile_s" in es:
            row = f"{'  dynamax compile (per N)':<30}"
            row += "".join(f"{_fmt_s(t):>14}" for t in es["dynamax_compile_s"])
            lines.append(row)
        lines.append("")
        lines.append("peer time / ours (both timed alternately in the same process)")
        for name in names:
            if name == "ours":
                continue
            row = f"{CONTESTANTS[name].label:<30}"
            row += "".join(f"{_fmt(x, '.1f', 'x'):>14}" for x in es["speedup_vs_ours"][name])
            lines.append(row)
        notes = [(name, i, es["notes"][name][i]) for name in names for i in range(len(ns))
                 if es["notes"][name][i]]
        for name, i, note in notes:
            lines.append(f"  note: {name} at N={ns[i]:,}: {note}")
    mem = res.get("memory")
    if mem:
        ns = res["estep"]["N"]
        lines.append("")
        lines.append("peak memory of one call: RSS growth MB / Python-tracked peak MB")
        for name, mm in mem.items():
            row = f"{CONTESTANTS[name].label:<30}"
            for r, p in zip(mm["rss_growth_mb"], mm["python_peak_mb"], strict=True):
                row += f"{'-' if r is None else f'{r:.0f} / {p:.0f}':>14}"
            lines.append(row)
    prof = res.get("profile")
    if prof:
        lines.append("")
        lines.append(f"profile of ours at N={prof['N']:,}: total {_fmt_s(prof['total_s'])}")
        lines.append(f"  CPU time split: user {_fmt_s(prof['user_s'])}, kernel "
                     f"{_fmt_s(prof['kernel_s'])} ({prof['page_faults_per_call']:.0f} minor "
                     f"page faults: first touch of fresh output memory)")
        for k, v in prof.get("stages_s", {}).items():
            lines.append(f"  {k:<40}{_fmt_s(v):>12}  ({100 * v / prof['total_s']:.1f} %)")
        if "stages_error" in prof:
            lines.append("  " + prof["stages_error"])
        lines.append("  cProfile, by own time per call:")
        for row in prof["cprofile_top"][:8]:
            lines.append(f"    {row['function'][:60]:<60}{_fmt_s(row['tottime_s']):>12}")
    lines.append("")
    em = res.get("offline_em_60s")
    if em is not None:
        lines.append(f"offline EM, {em.get('seconds', EM_SECONDS):.0f} s flight "
                     f"({em.get('steps', '?')} steps), regressor M-step: "
                     f"{_fmt_s(res.get('offline_em_60s_s'))} "
                     f"({em.get('e_steps', '?')} E-steps, converged {em.get('converged')}, "
                     f"mass {_fmt(em.get('mass'), '.4f')} kg vs {em.get('mass_true')})")
    off = res.get("offline_default")
    if off is not None:
        lines.append(f"python -m pinquad.offline (defaults, 1 run): "
                     f"{_fmt_s(res.get('offline_default_s'))} [{off.get('status')}]"
                     + (f" {off.get('note')}" if off.get("note") else ""))
    disc = res.get("log_discovery_60s")
    if disc is not None:
        before = disc.get("before", {})
        picked = "; ".join(e + " " + ", ".join(f"{c:.4g}" for c in v["coefficients"])
                           for e, v in disc.get("selected", {}).items()) or "nothing"
        load = disc.get("loadavg_before", [math.nan])[0]
        lines.append(f"python -m pinquad.offline --log, 60 s at 500 Hz with drag (1 run): "
                     f"{_fmt_s(res.get('log_discovery_60s_s'))} [{disc.get('status')}] "
                     f"(load average {load:.1f}); selected {picked}; before the speed-up "
                     f"{_fmt_s(before.get('s'))} (commit {before.get('commit')}, "
                     f"{before.get('date')})"
                     + (f" {disc.get('note')}" if disc.get("note") else ""))
    on = res.get("online")
    if on is not None:
        if on.get("available"):
            lines.append(f"online update, {on['window']}-sample window ({on['n']} updates): "
                         f"p50 {on['p50_ms']:.2f} ms, p99 {on['p99_ms']:.2f} ms")
        else:
            lines.append(f"online update latency: not available ({on.get('reason', '')})")
    return "\n".join(lines)



def format_checks(results: list[CheckResult], n_steps: int) -> str:
    """The ``--check`` table: each peer's status and its largest smoothed-mean error
    relative to the state scale, on an ``n_steps``-step case."""
    lines = [f"smoothed means vs ours (pinquad.fast_smoother), N={n_steps:,}, "
             f"tolerance {TOLERANCE:.0e} of the state scale"]
    for r in results:
        err = "-" if r.error is None else f"{r.error:.1e}"
        lines.append(f"  {r.name:<16}{r.status:<10}{err:>10}  {r.message}")
    return "\n".join(lines)
