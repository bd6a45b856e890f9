"""Where a command's independent tasks run: the execution backend (docs/cluster.md).

Every command that runs many independent tasks (Monte Carlo cycles, flights, logs) maps a
module-level task function over picklable jobs through one ``concurrent.futures.Executor``
opened here, and reads the results back in the order of the jobs (``Executor.map``), never
in the order they finish. The task functions and their seeds are the same on every
backend, so the numbers are too:

- the local process pool (default): ``jobs`` worker processes; one job, or ``jobs`` = 1,
  runs in this process (no pool to start);
- ``scheduler``: an existing Dask distributed cluster, through the ``Executor`` that
  ``distributed.Client(address).get_executor()`` gives (its workers must see the same
  files: jobs carry paths, not data);
- ``cluster_workers`` = N (``--cluster local:N``): a Dask ``LocalCluster`` of N worker
  processes of one thread each, started for the run and closed after it.

Every task runs with one BLAS / OpenMP thread, whatever the backend: a Dask worker starts
with one (its nanny sets OPENBLAS_NUM_THREADS=1), a pool worker would inherit as many as
the machine has cores, and the thread count changes the last digits of BLAS reductions
(measured: discovery's refit coefficients moved by ~1e-7 relative). Pinned, the same
task gives the same bits on every backend, and N workers use N cores, not N x cores.

Dask (the ``distributed`` package, ``pip install 'pinquad[cluster]'``) is imported only
when asked for, inside ``open_executor``: the package works without it.
"""

from __future__ import annotations

import contextlib
import logging
import re
import socket
from collections.abc import Callable, Iterator
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any

from threadpoolctl import threadpool_limits

CLUSTER_SPEC = re.compile(r"local:(\d+)")
"""``--cluster`` spec: ``local:N``, a local Dask cluster of N >= 1 worker processes."""

INSTALL_HINT = "pip install 'pinquad[cluster]'"


class BackendError(ValueError):
    """A backend that cannot be had: a bad ``--cluster`` spec, an unreachable
    ``--scheduler``, or Dask asked for without ``distributed`` installed. The message is
    one paragraph for the user (the commands exit 2 with it)."""


def parse_cluster_spec(spec: str) -> int:
    """The number of workers N of a ``--cluster local:N`` spec (N >= 1); BackendError
    naming the spec and the expected form otherwise."""
    match = CLUSTER_SPEC.fullmatch(spec.strip())
    if match is None or int(match.group(1)) < 1:
        raise BackendError(f"--cluster {spec!r}: expected local:N, a local Dask cluster of "
                           "N >= 1 worker processes (e.g. local:2); for an existing cluster "
                           "give --scheduler ADDRESS")
    return int(match.group(1))


@dataclass(frozen=True)
class Backend:
    """Where tasks run.

    jobs: worker processes of the local process pool (>= 1; 1 runs in this process);
        ignored by the Dask backends, whose workers the cluster has.
    scheduler: address of a running Dask scheduler (``tcp://HOST:PORT``), or None.
    cluster_workers: N of a local Dask cluster of N single-threaded worker processes
        (``--cluster local:N``), or None. At most one of scheduler, cluster_workers.
    connect_timeout_s: how long [s] to try to reach ``scheduler`` before giving up.
    """

    jobs: int = 1
    scheduler: str | None = None
    cluster_workers: int | None = None
    connect_timeout_s: float = 10.0

    def __post_init__(self) -> None:
        if self.jobs < 1:
            raise BackendError(f"--jobs {self.jobs}: expected a whole number >= 1")
        if self.scheduler is not None and self.cluster_workers is not None:
            raise BackendError("--scheduler and --cluster name two backends; give one")
        if self.cluster_workers is not None and self.cluster_workers < 1:
            raise BackendError(f"--cluster local:{self.cluster_workers}: expected N >= 1")

    @property
    def dask(self) -> bool:
        """True when the tasks go to a Dask cluster."""
        return self.scheduler is not None or self.cluster_workers is not None

    def describe(self) -> str:
        """The backend in words, for a command's banner."""
        if self.scheduler is not None:
            return f"Dask cluster at {self.scheduler}"
        if self.cluster_workers is not None:
            return f"local Dask cluster of {self.cluster_workers} worker(s)"
        return f"{self.jobs} worker process(es)" if self.jobs > 1 else "1 worker (this process)"


@dataclass(frozen=True)
class OneThreadTask:
    """``fn`` called with BLAS and OpenMP limited to one thread in the calling process
    (module docstring); picklable when ``fn`` is (a module-level function)."""

    fn: Callable[..., Any]

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        with threadpool_limits(limits=1):
            return self.fn(*args, **kwargs)


class OneThreadExecutor(Executor):
    """The backend's Executor with every task wrapped in ``OneThreadTask``: what
    ``open_executor`` yields, so no backend runs a task any other way."""

    def __init__(self, inner: Executor):
        self.inner = inner

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        return self.inner.submit(OneThreadTask(fn), *args, **kwargs)

    def map(self, fn: Callable[..., Any], *iterables: Any, timeout: float | None = None,
            chunksize: int = 1) -> Iterator[Any]:
        """``fn`` over ``iterables``, the results in their order (not of finishing)."""
        return self.inner.map(OneThreadTask(fn), *iterables, timeout=timeout,
                              chunksize=chunksize)

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        self.inner.shutdown(wait=wait)


class InProcessExecutor(Executor):
    """An Executor that runs each task at once in this process (the pool of one worker:
    no process to start, the same task functions and order as the pool)."""

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        future: Future = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # noqa: BLE001 - handed to the caller by result()
            future.set_exception(exc)
        return future

    def map(self, fn: Callable[..., Any], *iterables: Any, timeout: float | None = None,
            chunksize: int = 1, **kwargs: Any) -> Iterator[Any]:
        """Lazily, one task at a time as the caller asks (a progress bar sees each)."""
        return map(fn, *iterables)


def scheduler_problem(address: str, timeout_s: float) -> str | None:
    """None when ``address`` is a Dask scheduler address whose TCP port answers within
    ``timeout_s`` [s] (other transports are left to the client), else what is wrong."""
    from distributed.comm.addressing import parse_address, parse_host_port  # optional
    from distributed.comm.registry import get_backend

    try:
        scheme, location = parse_address(address)
        get_backend(scheme)  # ValueError naming the known schemes
        host, port = parse_host_port(location)
    except ValueError as exc:
        return str(exc)
    if scheme not in ("tcp", "tls"):
        return None
    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            return None
    except OSError as exc:
        return f"{host}:{port}: {exc.strerror or exc}"


@contextlib.contextmanager
def open_executor(backend: Backend, tasks: int | None = None) -> Iterator[Executor]:
    """The backend's Executor for the ``with`` block, closed after it.

    tasks: how many tasks will be mapped, if known (the process pool starts no more
    workers than tasks). Raises BackendError before any task runs when the backend
    cannot be had (module docstring).
    """
    if not backend.dask:
        workers = backend.jobs if tasks is None else max(1, min(backend.jobs, tasks))
        if workers == 1:
            yield OneThreadExecutor(InProcessExecutor())
        else:
            with ProcessPoolExecutor(max_workers=workers) as pool:
                yield OneThreadExecutor(pool)
        return
    try:
        import distributed  # optional and heavy: only when a Dask backend is asked for
    except ImportError:
        raise BackendError(
            f"{'--scheduler' if backend.scheduler is not None else '--cluster'} runs the "
            "tasks on a Dask cluster, which needs the optional dependency 'distributed' "
            f"(not installed): {INSTALL_HINT}, or leave the option out to use the local "
            "process pool (--jobs)") from None
    with contextlib.ExitStack() as stack:
        if backend.cluster_workers is not None:
            cluster = stack.enter_context(distributed.LocalCluster(
                n_workers=backend.cluster_workers, threads_per_worker=1, processes=True,
                dashboard_address=None, silence_logs=logging.ERROR))
            target: Any = cluster
        else:
            target = backend.scheduler
            # A Client that fails to connect lingers and times out again, with a traceback,
            # when the interpreter exits: reach the address before making one.
            problem = scheduler_problem(backend.scheduler, backend.connect_timeout_s)
            if problem is not None:
                raise BackendError(
                    f"--scheduler {backend.scheduler}: no Dask scheduler reached there "
                    f"({problem}); expected the address of a running scheduler, e.g. "
                    "tcp://HOST:8786")
        try:
            client = stack.enter_context(distributed.Client(
                target, timeout=f"{backend.connect_timeout_s}s", set_as_default=False))
        except (OSError, TimeoutError, ValueError) as exc:
            raise BackendError(f"{backend.describe()}: could not connect ({exc})") from None
        # pure=False: every task is run, none is taken from an earlier identical call
        executor = client.get_executor(pure=False)
        try:
            yield OneThreadExecutor(executor)
        except BaseException:
            executor.shutdown(wait=False)
            raise
        executor.shutdown(wait=True)


def worker_pool(jobs: int) -> contextlib.AbstractContextManager[Executor | None]:
    """``jobs`` worker processes for one log's identification and discovery
    (``pipeline.identify.identify_log``, ``pipeline.discover.run_discovery``), as a context
    manager: the process pool of :func:`open_executor` (one BLAS thread per task, as on
    every backend); None (no pool: all in this process) for jobs <= 1."""
    return open_executor(Backend(jobs=jobs)) if jobs > 1 else contextlib.nullcontext()
