"""Where the archive's partitions run: :func:`run_with_engine` chooses, :func:`map_partitions` runs them.

A command wraps its whole job — an ingest, a report's collection — in
:func:`run_with_engine`; the archive code inside it calls
:func:`map_partitions` at the point where it would loop over its
partitions (the files an ingest parses on the workers: :mod:`console.archive.ingest_cluster`).  The
engine is held in a context variable, so nothing between the command and
the archive's derivation passes it along, and the archive code runs
unchanged on the local engine (the default) in every other caller.

On Dask every partition is one task; the arguments all partitions share
(the archive root, the manifest, the speed settings) are sent to the
cluster once.  Results come back as one list in the order the partitions
were given, whatever ran where and whenever it finished, so what the
caller combines from it — and every byte it writes — is the same on every
engine and every number of workers.

A worker that dies (killed, over its memory limit) loses its tasks; the
scheduler runs them again on another worker from the same inputs, so the
answer is the same, later.  A partition that kills
``distributed.scheduler.allowed-failures`` workers in turn, or a cluster
that goes away, ends the run with one line (:class:`FleetError`); an
error raised by the partition function itself is raised again as itself,
for the caller's own one-line handling.  Nothing here writes to the
archive; what the tasks write (parts under fresh names) is seen only once
the caller publishes a manifest naming it (:func:`console.archive.store.publish`),
so a failed run leaves the archive as it was.
"""

from __future__ import annotations

import contextlib
import contextvars
import gc
import sys
import time
import uuid
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar

from console.fleet.cluster import open_client, quiet_logs
from console.fleet.options import EngineSpec, FleetError
from console.fleet.progress import task_progress
from console.memory import trim_heap

if TYPE_CHECKING:
    from distributed import Client, Future
    from rich.console import Console
    from rich.progress import Progress

R = TypeVar("R")
T = TypeVar("T")


@dataclass(frozen=True)
class TaskSpan:
    """One :func:`map_partitions` call as this process saw it: its label, its wall clock (``perf_counter``)
    and this process's CPU clock (``process_time``) at its start and end.  On a cluster the client only waits
    meanwhile; what lies outside every span is the client's own serial work (benchmarks/bench_fleet.py)."""

    label: str
    tasks: int
    wall0: float
    wall1: float
    cpu0: float
    cpu1: float


class _Engine:
    """Runs partitions here, one after the other (the local engine)."""

    def __init__(
        self, console: Console | None = None, progress: bool = False, host: Callable[[], Progress | None] | None = None
    ) -> None:
        self.console = console
        self.progress = progress
        self.host = host
        self.spans: list[TaskSpan] = []  # every map call of this engine's scope, in order

    def bar(self, total: int, label: str) -> contextlib.AbstractContextManager[Callable[[int], None]]:
        host = self.host() if self.host is not None else None
        return task_progress(total if self.progress else 0, label, self.console, host)

    def map(
        self, fn: Callable[..., R], items: Sequence[Mapping[str, Any]], common: Mapping[str, Any], label: str
    ) -> list[R]:
        wall0, cpu0 = time.perf_counter(), time.process_time()
        out = list(self.imap(fn, items, common, label))
        self.spans.append(TaskSpan(label, len(items), wall0, time.perf_counter(), cpu0, time.process_time()))
        return out

    def imap(
        self, fn: Callable[..., R], items: Sequence[Mapping[str, Any]], common: Mapping[str, Any], label: str
    ) -> Iterator[R]:
        """The results one by one, in the order of ``items``: the caller holds only the one it is given."""
        with self.bar(len(items), label) as done:
            for item in items:
                yield fn(**common, **item)
                done(1)


class _DaskEngine(_Engine):
    """Runs partitions as tasks of a connected Dask client."""

    def __init__(
        self,
        client: Client,
        console: Console | None = None,
        progress: bool = False,
        host: Callable[[], Progress | None] | None = None,
    ) -> None:
        super().__init__(console, progress, host)
        self.client = client
        self.warming: list[Future] = []  # warm_workers' imports, held for the scope

    def imap(
        self, fn: Callable[..., R], items: Sequence[Mapping[str, Any]], common: Mapping[str, Any], label: str
    ) -> Iterator[R]:
        """The results in the order of ``items``, each fetched as soon as it and those before it are done.

        At most :func:`in_flight` tasks run at once: the cluster stays busy, and the results waiting here
        for an earlier one to finish stay few (a list of every result would grow with the archive).
        """
        from collections import deque

        if not items:
            return
        client = self.client
        run = uuid.uuid4().hex[:12]  # task names unique on a shared scheduler
        # Shared arguments once to the cluster, not once per task (the manifest lists every part).  As tasks,
        # not scattered data: a value held only by a worker that dies is computed again, where scattered
        # data would be lost with it and every partition needing it cancelled.
        shared = {k: client.submit(_value, v, key=f"trackside-common-{run}-{k}", pure=False) for k, v in common.items()}
        window = in_flight()
        pending: deque[tuple[int, Future]] = deque()
        submitted: list[Future] = []

        def submit(i: int) -> None:
            # The arguments as one dict (their names may clash with submit's own: key, workers, …).
            fut = client.submit(_call, fn, {**shared, **items[i]}, key=f"trackside-{label}-{run}-{i}", pure=False)
            pending.append((i, fut))
            submitted.append(fut)

        try:
            with self.bar(len(items), label) as done:
                nxt = 0
                while nxt < len(items) and len(pending) < window:
                    submit(nxt)
                    nxt += 1
                while pending:
                    i, fut = pending.popleft()
                    try:
                        # Fetched and released at once: a worker holds no finished result, so its memory stays
                        # that of the partition it runs (results left on the workers would spill and pause them).
                        result = fut.result()
                    except Exception:
                        if fut.status == "error":
                            _raise_for(fut, items[i])
                        raise
                    fut.release()
                    if nxt < len(items):
                        submit(nxt)
                        nxt += 1
                    done(1)
                    yield result
        except FleetError:
            raise
        except Exception as exc:
            if _is_cluster_failure(exc):
                raise FleetError(f"the dask cluster failed during the run: {_line(exc)}; archive unchanged") from None
            raise
        finally:
            client.cancel([*submitted, *shared.values()])


def warm_workers(modules: Sequence[str]) -> None:
    """On a cluster, each worker imports ``modules`` now, in the background, while this process does its own
    first steps: otherwise every worker's first task pays for them after those steps, one after the other.
    Nothing here waits; the tasks that follow queue behind the import on each worker."""
    engine = _current.get()
    if not isinstance(engine, _DaskEngine) or not modules:
        return
    client = engine.client
    for address in client.scheduler_info()["workers"]:
        # Held for the scope: a released future's task may be dropped.
        engine.warming.append(client.submit(_import_modules, tuple(modules), workers=[address], pure=False))


def _import_modules(modules: tuple[str, ...]) -> None:
    import importlib

    for name in modules:
        importlib.import_module(name)


def task_spans() -> list[TaskSpan]:
    """The :func:`map_partitions` calls made so far in the current engine's scope (none outside one)."""
    engine = _current.get()
    return list(engine.spans) if engine is not None else []


def on_cluster() -> bool:
    """The current engine is a Dask cluster (work is split into tasks that run elsewhere)."""
    return getattr(_current.get(), "client", None) is not None


def in_flight() -> int:
    """How many partition tasks to have running at once on the current engine: two per worker thread on a
    cluster (one running, one queued behind it), one here."""
    client = getattr(_current.get(), "client", None)
    if client is None:
        return 1
    return max(2, 2 * sum(client.nthreads().values()))


def _value(v: T) -> T:
    return v


# None: the local engine without a bar (every caller outside run_with_engine: tests, the library).
def _call(fn: Callable[..., R], kwargs: Mapping[str, Any]) -> R:
    """One task: the partition function with its arguments (futures in the dict resolved by the worker).

    What the task freed is given back to the system at its end.  A worker whose process memory stays
    above dask's pause fraction (80 % of its limit) takes no further task, and an idle worker frees
    nothing by itself: a 100 M-record ingest on one worker waited forever at 436 MB of 512."""
    try:
        return fn(**kwargs)
    finally:
        if _memory_worth_collecting():
            gc.collect()
        arrow = sys.modules.get("pyarrow")
        if arrow is not None:
            arrow.default_memory_pool().release_unused()
        trim_heap()


def _memory_worth_collecting() -> bool:
    """Whether the worker that ran a task holds enough memory for a full collection to be worth its cost.

    A full collection scans every object of the worker's heap, pandas', pyarrow's and duckdb's modules
    included: 50-100 ms of CPU, most of the CPU of a small task (a few hundred of them made a 4-route test
    case a third slower).  Below half the worker's memory limit (dask pauses a worker at 80 %) the collector's
    own thresholds are left to run it; above, and where no limit is known, every task ends with one."""
    try:
        from distributed import get_worker

        worker = get_worker()
        limit = worker.memory_manager.memory_limit
        return not limit or worker.monitor.get_process_memory() >= limit // 2
    except (ValueError, AttributeError):  # not on a worker, or a distributed without these: as before
        return True


_current: contextvars.ContextVar[_Engine | None] = contextvars.ContextVar("trackside_fleet_engine", default=None)


def map_partitions(
    fn: Callable[..., R],
    items: Sequence[Mapping[str, Any]],
    *,
    common: Mapping[str, Any] | None = None,
    label: str = "partitions",
) -> list[R]:
    """``[fn(**common, **item) for item in items]`` on the current engine, in the order of ``items``.

    ``fn`` must be a module-level function (Dask sends it to the workers by
    name) that reads what it needs and writes nothing; ``common`` holds the
    arguments every call shares, sent to a cluster once.  Outside
    :func:`run_with_engine` this is the plain local loop.
    """
    engine = _current.get() or _Engine()
    return engine.map(fn, items, common or {}, label)


def run_with_engine(
    spec: EngineSpec,
    job: Callable[[], T],
    *,
    say: Callable[[str], None] | None = None,
    console: Console | None = None,
    progress: bool = True,
    host: Callable[[], Progress | None] | None = None,
) -> T:
    """Run ``job()`` with its :func:`map_partitions` calls on the engine ``spec`` names.

    ``--engine dask --workers N`` starts a LocalCluster for the job and stops
    it after, whatever happens; ``--scheduler`` connects to an existing one.
    ``say`` hears one-line notes (the cluster, its dashboard); with
    ``progress`` a bar of partitions done / total goes to ``console``
    (default: stderr) when it is a terminal; ``host`` gives the bar the
    command already shows, if any (the tasks then get a line in it: Rich
    shows one live display at a time).
    """
    with engine_scope(spec, say=say, console=console, progress=progress, host=host):
        return job()


@contextlib.contextmanager
def engine_scope(
    spec: EngineSpec,
    *,
    say: Callable[[str], None] | None = None,
    console: Console | None = None,
    progress: bool = True,
    host: Callable[[], Progress | None] | None = None,
) -> Iterator[None]:
    """The engine of ``spec`` current for the block (a LocalCluster, if any, lives as long as the block)."""
    if spec.kind == "local":
        token = _current.set(_Engine(console, progress, host))
        try:
            yield
        finally:
            _current.reset(token)
        return
    with open_client(spec, say) as client, quiet_logs():
        engine = _DaskEngine(client, console, progress, host)
        token = _current.set(engine)
        try:
            yield
        finally:
            _current.reset(token)
            client.cancel(engine.warming)


def _raise_for(fut: Future, item: Mapping[str, Any]) -> None:
    exc = fut.exception()
    if exc is None:
        return
    what = _describe(item)
    if _is_killed_worker(exc):
        raise FleetError(
            f"partition {what}: the workers running it died repeatedly (out of memory or killed); archive unchanged"
        ) from None
    if _is_cluster_failure(exc):
        raise FleetError(f"partition {what}: the dask cluster failed: {_line(exc)}; archive unchanged") from None
    raise exc  # the partition function's own error: the caller's one-line handling applies


def _describe(item: Mapping[str, Any]) -> str:
    """A partition in a few words: its name (device/day), or device and days of a derivation task."""
    obj = item.get("key", item.get("item", next(iter(item.values()), "?")))
    name = getattr(obj, "name", None)
    days = getattr(obj, "days", None)
    if name is None and days and hasattr(obj, "device_id"):
        name = f"{obj.device_id}/{days[0]}" + (f"..{days[-1]}" if len(days) > 1 else "")
    text = " ".join(str(obj if name is None else name).split())
    return text if len(text) <= 80 else text[:79] + "…"


def _is_killed_worker(exc: BaseException) -> bool:
    from distributed.scheduler import KilledWorker

    return isinstance(exc, KilledWorker)


def _is_cluster_failure(exc: BaseException) -> bool:
    from distributed.client import FutureCancelledError
    from distributed.comm.core import CommClosedError

    return _is_killed_worker(exc) or isinstance(
        exc, CommClosedError | TimeoutError | ConnectionError | FutureCancelledError
    )


def _line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__
