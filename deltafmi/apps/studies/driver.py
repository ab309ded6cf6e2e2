"""The client side of a sweep: a Dask cluster, tasks of a few cases each, results stored as they come.

By default the study runs on a :class:`distributed.LocalCluster` of worker processes (one thread
each) on this machine; with a scheduler address it runs on that cluster instead. Either way the
FMUs built here travel to the workers inside a worker plugin (:mod:`deltafmi.apps.studies.worker`) and
each task carries only its cases' values (:mod:`deltafmi.apps.studies.batches` decides how many). A
worker process that dies is restarted by its Dask nanny; the cases of the task it was running
run again, each in a task of its own, and a case that kills the worker running it alone is
recorded as failed (``KilledWorker``) and the study goes on. On the local cluster
``worker-saturation`` is 1.0, so a worker holds only the task it runs and a death is that task's,
and ``allowed-failures`` is 0, so Dask reports the death at once and the retry above is the only
one. A cluster given by address keeps its own settings of both (Dask then retries a task as they
say before the retry above). A case that fails inside the simulation is a result row like any other.

The local cluster's scheduler serves Dask's dashboard and HTTP pages (worker logs, call stacks,
task details) on 127.0.0.1 only, unless the caller gives another address (``dashboard``).
"""
from __future__ import annotations

import dataclasses
import logging
import os
import sys
import time as _time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Container, Dict, Iterator, List, Optional, TextIO, Tuple

from distributed import WorkerPlugin

from deltafmi.errors import BadInput, SimulationError

from .batches import Batch, Batcher
from .cases import Case
from .plan import PlannedStudy
from .remote import CONNECT_TIMEOUT, connect
from .runner import FAILED, OK, CaseResult
from .store import ResultStore
from .worker import StudyPlugin, from_message, run_cases_task

__all__ = ["LOCAL_DASHBOARD", "dashboard_address", "dashboard_link", "dask_client", "open_store", "run_study",
           "summary_lines", "sweep_study"]

#: seconds between rewrites of the results table while the study runs
TABLE_EVERY = 10.0
#: seconds between progress lines when the output is not a terminal
LINE_EVERY = 30.0
#: workers send each case's result as it finishes, when the study keeps no time series (see run_study)
STREAM_RESULTS = True


@dataclass
class SweepReport:
    """How a sweep went."""

    total: int
    reused: int
    ran: int
    failed: int
    wall_time: float
    workers: int
    interrupted: bool = False
    #: seconds to connect and to register the study on the workers (FMUs shipped, unpacked, resolved)
    setup_time: float = 0.0

    @property
    def rate(self) -> float:
        """Cases run per wall-clock second in this session."""
        return self.ran / self.wall_time if self.wall_time > 0 else 0.0


class StudyProgress:
    """``[#######.......]  42/91 cases, 2 failed, 1.9 cases/s, ETA 0:27`` redrawn at most 5x/s on a
    terminal; with ``lines`` (the output is a log file, CI), ``42/91 cases, ...`` as a line of its
    own every :data:`LINE_EVERY` seconds."""

    def __init__(self, total: int, reused: int, enabled: bool, stream: TextIO = sys.stdout,
                 lines: bool = False) -> None:
        self.total, self.done, self.failed = total, reused, 0
        self.ran = 0
        self.enabled, self.stream = enabled or lines, stream
        self.lines = lines and not enabled
        self.start = _time.monotonic()
        self._next = 0.0 if not self.lines else self.start + LINE_EVERY

    def add(self, result: CaseResult) -> None:
        """Count one finished case."""
        self.done += 1
        self.ran += 1
        self.failed += result.status == FAILED
        self.draw()

    def draw(self, force: bool = False) -> None:
        """Redraw the line (rate limited unless ``force``)."""
        if not self.enabled:
            return
        now = _time.monotonic()
        if now < self._next and not force:
            return
        self._next = now + (LINE_EVERY if self.lines else 0.2)
        elapsed = now - self.start
        rate = self.ran / elapsed if elapsed > 0 else 0.0
        left = self.total - self.done
        eta = f"ETA {_clock(left / rate)}" if rate > 0 and left else ("done" if not left else "ETA ?")
        counts = f"{self.done}/{self.total} cases, {self.failed} failed, {rate:.2f} cases/s, {eta}"
        if self.lines:
            if not force:
                self.stream.write(counts + "\n")
                self.stream.flush()
            return
        filled = int(30 * self.done / max(self.total, 1))
        self.stream.write(f"\r[{'#' * filled}{'.' * (30 - filled)}] {counts}   ")
        self.stream.flush()

    def close(self) -> None:
        """Finish the line."""
        if self.enabled and not self.lines:
            self.draw(force=True)
            self.stream.write("\n")
            self.stream.flush()
        self.enabled = False


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    return (f"{hours}:" if hours else "") + f"{rest // 60:0{2 if hours else 1}d}:{rest % 60:02d}"


def local_workers() -> int:
    """Worker processes of the default local cluster: one per core this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


#: where the local cluster's dashboard listens unless asked otherwise: this machine only, a free port
LOCAL_DASHBOARD = "127.0.0.1:0"


def dashboard_address(text: str) -> Tuple[str, int]:
    """``HOST:PORT``, ``HOST`` (a free port), ``PORT`` (on 127.0.0.1) or ``[IPv6]:PORT`` -> (host, port).

    Dask reads ``:PORT`` as every interface; that form is refused so that exposing the dashboard
    is always spelt out (``0.0.0.0:PORT``).
    """
    def bad(why: str) -> BadInput:
        return BadInput(f"--dashboard {text!r}: {why}; expected HOST:PORT, e.g. 127.0.0.1:8787 "
                        "(this machine only) or 0.0.0.0:8787 (every interface)")

    text = text.strip()
    if text.startswith("["):
        host, sep, rest = text[1:].partition("]")
        if not sep or (rest and not rest.startswith(":")):
            raise bad("an IPv6 address goes in brackets, [::1]:8787")
        port_text = rest[1:] if rest else "0"
    elif text.isdigit():
        host, port_text = "127.0.0.1", text
    elif text.count(":") <= 1:
        host, _, port_text = text.partition(":")
        port_text = port_text or "0"
    else:
        raise bad("an IPv6 address goes in brackets, [::1]:8787")
    if not host:
        raise bad("no host (Dask would listen on every interface): name it")
    if not port_text.isdigit() or not 0 <= int(port_text) <= 65535:
        raise bad(f"the port {port_text!r} is not a number from 0 to 65535")
    return host, int(port_text)


@contextmanager
def dask_client(scheduler: Optional[str] = None, workers: Optional[int] = None,
                dashboard: str = LOCAL_DASHBOARD, security: Any = None,
                connect_timeout: float = CONNECT_TIMEOUT) -> Iterator[Any]:
    """A Dask client: of the cluster at ``scheduler`` (see :func:`deltafmi.apps.studies.remote.connect`
    for ``security`` and ``connect_timeout``), else of a new local cluster of ``workers``
    single-threaded worker processes (closed on exit) whose dashboard listens at ``dashboard``
    (see :func:`dashboard_address`; default 127.0.0.1, a free port)."""
    import dask
    from distributed import Client, LocalCluster

    if scheduler is not None:
        client = connect(scheduler, security, connect_timeout)
        try:
            yield client
        finally:
            client.close()
        return
    # A worker holds one task at a time (saturation 1.0): Dask counts a death against every task
    # assigned to the worker, so a task queued behind a crashing one must not be there. A death
    # is reported at once (allowed-failures 0): run_study retries the task's cases one by one.
    # Workers do not sample their own stacks every 10 ms for the dashboard's profile, the
    # processes check that their event loop is not blocked every second instead of every 20 ms,
    # the workers' and nannies' memory every second instead of every 100 ms, and the system
    # monitors (the dashboard's CPU and memory charts) take their sample every 2 s instead of
    # every 0.5 s; no work stealing (a worker holds only the task it runs: there is nothing to
    # steal). What an idle cluster costs goes on during every case, on a machine whose every
    # core runs a worker: that is time taken from the cases.
    host, port = dashboard_address(dashboard)
    with dask.config.set({"distributed.scheduler.allowed-failures": 0,
                          "distributed.scheduler.worker-saturation": 1.0,
                          "distributed.worker.profile.enabled": False,
                          "distributed.admin.tick.interval": "1s",
                          "distributed.worker.memory.monitor-interval": "1s",
                          "distributed.admin.system-monitor.interval": "2s",
                          "distributed.scheduler.work-stealing": False}):
        try:
            # a (host, port) pair: Dask's own parsing of a string splits IPv6 addresses at every colon
            cluster = LocalCluster(n_workers=workers or local_workers(), threads_per_worker=1, processes=True,
                                   dashboard_address=(host, port), silence_logs=logging.ERROR)
        except (OSError, RuntimeError) as exc:  # "Cluster failed to start" from an OSError of the bind
            reason = _os_error(exc)
            if reason is None:
                raise
            raise BadInput(f"cannot start the Dask dashboard at {dashboard}: {reason.strerror or reason}") from None
    client = Client(cluster)
    try:
        client.register_plugin(_IgnoreInterrupts(), name="deltafmi-ignore-interrupts")
        yield client
    finally:
        client.close()
        cluster.close()


def _os_error(exc: BaseException) -> Optional[OSError]:
    """The OSError in the chain of ``exc`` (Dask wraps a failed bind in a RuntimeError), if any."""
    seen: Optional[BaseException] = exc
    while seen is not None:
        if isinstance(seen, OSError):
            return seen
        seen = seen.__cause__ or seen.__context__
    return None


def dashboard_link(client: Any) -> str:
    """The status page of the local cluster of ``client`` at the address its dashboard listens on
    (Dask's own ``dashboard_link`` names 127.0.0.1 whatever the address)."""
    import socket

    server = client.cluster.scheduler.http_server
    host = socket.gethostname() if server.address in ("0.0.0.0", "::") else server.address
    return f"http://{f'[{host}]' if ':' in host else host}:{server.port}/status"


class _IgnoreInterrupts(WorkerPlugin):
    """Worker plugin of the local cluster: Ctrl-C in a terminal reaches every process of the
    group; the client handles it (cancels, saves, closes the cluster), the workers ignore it."""

    name = "deltafmi-ignore-interrupts"

    def setup(self, worker: Any) -> None:
        import signal
        import threading

        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, signal.SIG_IGN)


def open_store(planned: PlannedStudy, table: Path, timeseries: bool) -> ResultStore:
    """The result files of ``planned`` at ``table`` (Parquet), with the study described in them."""
    vary = planned.study.vary
    distributions = {t.name: d.describe() for t, d in vary.monte_carlo.parameters} if vary.monte_carlo else {}
    metadata = {
        "study": str(planned.study.path), "scenario": str(planned.study.scenario),
        "description": planned.study.description, "fingerprint": planned.plan.fingerprint,
        "cases": len(planned.cases),
        "targets": [{"name": t.name, "kind": vary.kind_of(t.name), "unit": planned.units.get(t.name, ""),
                     **({"distribution": distributions[t.name]} if t.name in distributions else {})}
                    for t in vary.targets],
        "metrics": [{**m.spec.as_dict(), "unit": m.unit} for m in planned.plan.metrics],
    }
    return ResultStore(table, planned.plan.fingerprint, planned.targets, [m.name for m in planned.plan.metrics],
                       metadata, timeseries)


def run_study(planned: PlannedStudy, store: ResultStore, todo: List[Case], *, scheduler: Optional[str] = None,
              workers: Optional[int] = None, progress: bool = False, progress_lines: bool = False,
              on_result: Callable[[CaseResult], None] = lambda result: None,
              dashboard: str = LOCAL_DASHBOARD,
              on_dashboard: Callable[[str], None] = lambda link: None,
              client: Any = None, security: Any = None,
              connect_timeout: float = CONNECT_TIMEOUT) -> SweepReport:
    """Run the cases ``todo`` of ``planned`` on Dask, storing every result in ``store`` (opened).

    On ``client`` when given (left open), else on the cluster at ``scheduler`` (``security`` and
    ``connect_timeout`` as in :func:`deltafmi.apps.studies.remote.connect`), else on a local cluster whose
    dashboard listens at ``dashboard``; ``on_dashboard`` gets its link once the cluster is up.
    ``progress``: a progress bar (a terminal); ``progress_lines``: a progress line every
    :data:`LINE_EVERY` seconds instead (a log file).
    Ctrl-C cancels what is left; the finished cases stay recorded (a re-run skips them).
    :func:`sweep_study` opens the store too, once the cluster answers.
    """
    import queue
    import uuid

    total = len(planned.cases)
    reused = total - len(todo)
    bar = StudyProgress(total, reused, progress, lines=progress_lines)
    wall = _time.perf_counter()
    ran = failed = 0
    setup = 0.0
    interrupted = False
    n_workers = 0
    if todo:
        plugin = StudyPlugin(planned.plan, planned.fmu_bytes)
        fingerprint = planned.plan.fingerprint
        keep = store.timeseries is not None
        # each case's result streamed as a Dask event of a topic of this run's own (time series
        # travel with the task's result only); the events and the finished tasks arrive in one queue
        topic = None if keep or not STREAM_RESULTS else f"deltafmi-results-{fingerprint[:12]}-{uuid.uuid4().hex[:12]}"
        arrived: "queue.SimpleQueue[Any]" = queue.SimpleQueue()
        with _client(client, scheduler, workers, dashboard, security, connect_timeout) as client:
            if client.cluster is None:  # a cluster given by address
                threads = [w["nthreads"] for w in client.scheduler_info(n_workers=-1)["workers"].values()]
                n_workers, slots = len(threads), sum(threads)
            else:
                n_workers = slots = workers or local_workers()
                on_dashboard(dashboard_link(client))
            try:
                client.register_plugin(plugin, name=plugin.name)
            except Exception as exc:  # noqa: BLE001 - e.g. a worker without deltafmi
                raise SimulationError(f"the Dask workers could not set up the study: {exc}") from None
            if topic is not None:
                client.subscribe_topic(topic, lambda event: arrived.put(event[1]))
            setup = _time.perf_counter() - wall
            batcher = Batcher(todo, slots, streamed=topic is not None)
            running: Dict[Any, Batch] = {}
            submitted: Dict[int, Case] = {}  # the cases of the tasks under way, by id
            recorded: set = set()  # the cases of this run whose result is in the store

            def submit() -> None:
                """Keep two tasks per worker thread submitted: one running, the next one waiting."""
                while batcher and len(running) < 2 * slots:
                    batch = batcher.next()
                    key = f"deltafmi-cases-{fingerprint[:12]}-{batch.cases[0].id}{'-alone' if batch.alone else ''}"
                    future = client.submit(run_cases_task, fingerprint, [(c.id, c.values) for c in batch.cases],
                                           keep, topic, key=key)
                    running[future] = batch
                    submitted.update((c.id, c) for c in batch.cases)
                    future.add_done_callback(arrived.put)

            def record(result: CaseResult) -> None:
                """Store a result (a case streamed already is not stored again)."""
                nonlocal ran, failed
                if result.case in recorded:
                    return
                store.add(result)
                recorded.add(result.case)
                submitted.pop(result.case, None)
                if result.wall_time > 0:
                    batcher.observe(result.wall_time)
                ran += 1
                failed += result.status == FAILED
                bar.add(result)
                on_result(result)

            def handle(item: Any) -> None:
                """Results streamed by a worker (a list of dicts), or a finished task (its future)."""
                if isinstance(item, (list, tuple)):  # msgpack may hand a list back as a tuple
                    for i, message in enumerate(item):
                        case = submitted.get(message.get("case")) if isinstance(message, dict) else None
                        try:
                            if case is not None:
                                record(from_message(message, case.values))
                        except BaseException:  # Ctrl-C: the rest of the list is stored by the drain
                            arrived.put(list(item[i + 1:]))
                            raise
                elif item in running and item.status != "cancelled":  # cancelled: its cases are not done
                    for result in _results(item, running.pop(item), batcher, recorded):
                        record(result)

            def handle_arrived() -> None:
                while True:
                    try:
                        handle(arrived.get_nowait())
                    except queue.Empty:
                        return

            submit()
            last_table = bar.start = _time.monotonic()  # rates and ETA from here, the cluster up
            bar.draw(force=True)
            try:
                while running:
                    try:
                        handle(arrived.get(timeout=1.0))
                    except queue.Empty:
                        continue
                    submit()
                    if _time.monotonic() - last_table > TABLE_EVERY:
                        store.write_tables(planned.cases)
                        last_table = _time.monotonic()
            except KeyboardInterrupt:
                interrupted = True
                client.cancel(list(running))
                handle_arrived()  # what the workers finished and sent is kept too
                store.sync_with_journal()  # the signal may have come between a case's journal line and its row
            finally:
                bar.close()
                try:
                    if topic is not None:
                        client.unsubscribe_topic(topic)
                    client.unregister_worker_plugin(plugin.name)
                except Exception:  # noqa: BLE001 - the cluster may be going down already
                    pass
    store.write_tables(planned.cases)
    return SweepReport(total, reused, ran, failed, _time.perf_counter() - wall, n_workers, interrupted, setup)


def sweep_study(planned: PlannedStudy, store: ResultStore, *, fresh: bool = False, retry_failed: bool = False,
                scheduler: Optional[str] = None, workers: Optional[int] = None, security: Any = None,
                connect_timeout: float = CONNECT_TIMEOUT, **options: Any) -> SweepReport:
    """Open ``store`` and run the cases of ``planned`` it has no result of (all with ``fresh``,
    the failed ones again with ``retry_failed``); ``options`` as for :func:`run_study`.

    The result files are checked first and changed only once the cluster answers: a ``fresh``
    sweep that cannot reach its scheduler leaves the earlier results as they were.
    """
    wall = _time.perf_counter()
    if not store.pending(planned.cases, fresh, retry_failed):  # nothing to run: no cluster
        store.open(planned.cases, fresh, retry_failed)
        return run_study(planned, store, [], **options)
    with dask_client(scheduler, workers, options.pop("dashboard", LOCAL_DASHBOARD), security,
                     connect_timeout) as client:
        todo = store.open(planned.cases, fresh, retry_failed)
        connecting = _time.perf_counter() - wall
        report = run_study(planned, store, todo, client=client, workers=workers, **options)
    return dataclasses.replace(report, wall_time=report.wall_time + connecting,
                               setup_time=report.setup_time + connecting)


@contextmanager
def _client(client: Any, scheduler: Optional[str], workers: Optional[int], dashboard: str, security: Any,
            connect_timeout: float) -> Iterator[Any]:
    """``client`` as it is, else a new one (closed on exit) as :func:`dask_client` makes it."""
    if client is not None:
        yield client
        return
    with dask_client(scheduler, workers, dashboard, security, connect_timeout) as made:
        yield made


def _results(future: Any, batch: Batch, batcher: Batcher, recorded: Container[int] = ()) -> List[CaseResult]:
    """The results of a finished task; none when its worker died and its cases not ``recorded``
    yet (streamed before the death) run again. A case the task says it streamed (its id in
    place of its result) whose result did not come runs again."""
    from distributed import KilledWorker

    try:
        returned = future.result()
        results: List[CaseResult] = [r for r in returned if isinstance(r, CaseResult)]
        lost = {r for r in returned if isinstance(r, int) and r not in recorded}
        if lost:
            batcher.run_again(Batch([c for c in batch.cases if c.id in lost]))
    except KilledWorker:
        if not batch.alone:
            batcher.run_again(Batch([c for c in batch.cases if c.id not in recorded]))
            return []
        case = batch.cases[0]
        return [CaseResult(case.id, case.values, {}, FAILED,
                           "the worker process died running this case (a crash in an FMU, or out of memory), "
                           "again when it ran alone; Dask restarted the worker each time (KilledWorker)")]
    except Exception as exc:  # noqa: BLE001 - a task that raised: record it, go on
        return [CaseResult(c.id, c.values, {}, FAILED, f"{type(exc).__name__}: {exc}") for c in batch.cases]
    return results


def summary_lines(planned: PlannedStudy, store: ResultStore, report: SweepReport,
                  signum: Optional[int] = None) -> List[str]:
    """The end-of-sweep summary: counts, rate, and min / median / mean / max of every metric (the
    mean of a 0/1 metric is a success rate); ``signum``: the signal that interrupted it."""
    import signal

    import numpy as np

    done = [(c, store.rows[c.key]) for c in planned.cases if c.key in store.rows]
    rows = [r for _, r in done]
    ok = [r for r in rows if r["status"] == OK]
    ran = (f"ran {report.ran} in {report.wall_time:.1f} s on {report.workers} worker(s): {report.rate:.2f} cases/s"
           if report.ran or report.interrupted else "nothing left to run")
    lines = [f"{planned.study.path.name}: {len(rows)}/{report.total} cases done, {len(ok)} ok, "
             f"{len(rows) - len(ok)} failed ({report.reused} from an earlier run); {ran}"]
    if report.interrupted:
        by = f" by {signal.Signals(signum).name}" if signum else ""
        lines.append(f"interrupted{by}: the {len(rows)} cases done are kept, in {store.table} and "
                     f"{store.journal.name} alike; run the same command again to continue where it stopped")
    names = [m.name for m in planned.plan.metrics]
    width = max(len(n) for n in names + ["metric"])
    lines.append(f"{'metric':<{width}}  {'min':>12} {'median':>12} {'mean':>12} {'max':>12}  unit")
    for name in names:
        values = np.array([r["metrics"].get(name, np.nan) for r in ok], dtype=float)
        values = values[np.isfinite(values)]
        stats = [f"{v:12.5g}" for v in (np.min(values), np.median(values), np.mean(values), np.max(values))] \
            if len(values) else [f"{'-':>12}"] * 4
        lines.append(f"{name:<{width}}  {' '.join(stats)}  {planned.units.get(name, '')}")
    failures = [(c, r) for c, r in done if r["status"] == FAILED]
    for case, row in failures[:5]:
        lines.append(f"failed: case {case.id} ({case.describe()}): {row['error']}")
    if len(failures) > 5:
        lines.append(f"... and {len(failures) - 5} more failed cases (column 'error' of the table)")
    lines.append(f"results: {store.table}, {store.csv}" + (f", {store.timeseries}/" if store.timeseries else ""))
    return lines
