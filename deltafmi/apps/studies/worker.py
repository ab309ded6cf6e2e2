"""The Dask side of a sweep: FMUs delivered to workers by a worker plugin, one task per case.

:class:`StudyPlugin` carries the study's plan and its FMU files as bytes. Dask gives a registered
plugin to every worker, including workers that join or are restarted later, so nothing has to be
shared between the client and the workers but the installed ``deltafmi``. On the worker the
plugin stores each FMU once in a cache keyed by its sha256 (``$DELTAFMI_CACHE/study-fmus``) and
the process keeps one :class:`WorkerCache`: the FMU pool (loaded FMUs, reset between cases) and
the resolved case template of each study. :func:`run_cases_task` is the task: it carries only the
study's fingerprint and a batch of case ids with their values, and sends each case's result to the
client as soon as it is done (a Dask event) besides returning them all at the end.
"""
from __future__ import annotations

import atexit
import gc
import hashlib
import threading
import time as _time
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Tuple, Union

from distributed import WorkerPlugin

from deltafmi.toolchain import cache_dir
from deltafmi.files import replaced_atomically

from .plan import StudyPlan
from .pool import FmuPool
from .runner import CaseResult, CaseTemplate, run_case

__all__ = ["StudyPlugin", "WorkerCache", "from_message", "result_message", "run_cases_task"]


class WorkerCache:
    """Per process: FMU files by hash, the FMU pool, and each study's case template."""

    def __init__(self, root: Optional[Path] = None) -> None:
        self.fmu_dir = Path(root) if root is not None else cache_dir() / "study-fmus"
        self.files: Dict[str, Path] = {}
        self.pool = FmuPool()
        self.plans: Dict[str, StudyPlan] = {}
        self._templates: Dict[str, CaseTemplate] = {}
        self._lock = threading.Lock()

    def add_fmus(self, blobs: Mapping[str, bytes]) -> None:
        """Store FMU files given as ``{sha256: bytes}`` (a file already there is kept)."""
        self.fmu_dir.mkdir(parents=True, exist_ok=True)
        for digest, data in blobs.items():
            path = self.fmu_dir / f"{digest}.fmu"
            if not path.is_file() or _sha256(path) != digest:
                if hashlib.sha256(data).hexdigest() != digest:
                    raise ValueError(f"FMU bytes do not match their hash {digest}")
                with replaced_atomically(path) as temporary:  # other workers may share the folder
                    temporary.write_bytes(data)
            self.files[digest] = path

    def add_plan(self, plan: StudyPlan) -> None:
        """Make ``plan`` runnable here."""
        self.plans[plan.fingerprint] = plan

    def template(self, fingerprint: str) -> CaseTemplate:
        """The case template of a study (resolved at its first case here)."""
        with self._lock:
            template = self._templates.get(fingerprint)
            if template is None:
                plan = self.plans.get(fingerprint)
                if plan is None:
                    raise RuntimeError(f"study {fingerprint[:12]} is not registered on this worker")
                template = self._templates[fingerprint] = CaseTemplate(plan, self.files)
            return template

    def use_folder(self, folder: Path) -> None:
        """Extract FMUs under ``folder`` from now on, if none was loaded yet. A Dask worker's own
        directory: Dask removes it when the worker stops, and after a crash at the next start."""
        with self._lock:
            if self.pool.created == 0:
                self.pool = FmuPool(Path(folder) / "deltafmi-pool")

    def remove_plan(self, fingerprint: str) -> None:
        """Forget a study and free the loaded FMUs no other study here uses (all of them, and
        their folder, when no study is left)."""
        plan = self.plans.pop(fingerprint, None)
        self._templates.pop(fingerprint, None)
        if plan is None:
            return
        still_used = {digest for other in self.plans.values() for _, digest in other.fmus}
        for _, digest in plan.fmus:
            if digest not in still_used and digest in self.files:
                self.pool.forget(str(self.files[digest]))
        if not self.plans:
            self.pool.close()


#: seconds between two sends of the results a task has finished (one event each: an event per case
#: costs the worker more than the case's own set-up)
STREAM_SECONDS = 0.25

_CACHE: Optional[WorkerCache] = None
_CACHE_LOCK = threading.Lock()


def worker_cache() -> WorkerCache:
    """This process's :class:`WorkerCache`."""
    global _CACHE
    with _CACHE_LOCK:
        if _CACHE is None:
            _CACHE = WorkerCache()
            atexit.register(_close_pool)
        return _CACHE


def _close_pool() -> None:
    """At the exit of the process: free the loaded FMUs and remove their folder."""
    if _CACHE is not None:
        _CACHE.pool.close()


class StudyPlugin(WorkerPlugin):
    """Delivers a study (plan and FMU bytes) to every worker of the cluster."""

    def __init__(self, plan: StudyPlan, blobs: Mapping[str, bytes]) -> None:
        self.plan = plan
        self.blobs = dict(blobs)
        self.name = f"deltafmi-study-{plan.fingerprint[:16]}"

    def setup(self, worker: Any) -> None:
        cache = worker_cache()
        cache.use_folder(Path(worker.local_directory))
        cache.add_fmus(self.blobs)
        cache.add_plan(self.plan)
        cache.template(self.plan.fingerprint)  # resolve now: a problem shows at registration

    def teardown(self, worker: Any) -> None:
        worker_cache().remove_plan(self.plan.fingerprint)


def run_cases_task(fingerprint: str, cases: List[Tuple[int, Dict[str, Any]]],
                   keep_timeseries: bool, topic: Optional[str] = None) -> List[Union[CaseResult, int]]:
    """The Dask task of a batch of cases ``(id, values)`` (runs on a worker): their results. With
    ``topic``, the cases' results are sent to the client as they finish, as Dask events of that
    topic (a list of :func:`result_message`, at most every :data:`STREAM_SECONDS`; the client
    subscribes): what a batch has done reaches the client's result files before the batch ends.
    The task then returns only the id of a case whose result went as an event (the client checks
    that it came), and the results it did not send."""
    from distributed import get_worker

    cache = worker_cache()
    try:
        worker: Any = get_worker()
        address = worker.address
    except ValueError:  # not on a worker (called directly)
        worker, address = None, "local"
    template = cache.template(fingerprint)
    results: List[Union[CaseResult, int]] = []
    unsent: List[Dict[str, Any]] = []
    sent = _time.monotonic()

    def send() -> None:
        nonlocal unsent, sent
        if unsent:
            worker.log_event(topic, unsent)
            n = len(unsent)
            results[-n:] = [int(message["case"]) for message in unsent]  # sent: the id is enough
        unsent, sent = [], _time.monotonic()

    streaming = topic is not None and worker is not None
    # what the process holds now (Dask's state, the loaded FMUs, the templates: most of its objects)
    # is left out of the garbage collections the cases trigger, which then look at the cases' own
    # objects only: a full collection over everything cost a Dask worker about 1 ms per case more
    # than a plain process
    gc.freeze()
    try:
        for case, values in cases:
            if results and worker is not None and _cancelled(worker):
                if streaming:
                    send()  # the client takes nothing from a cancelled task but its events
                break
            results.append(run_case(template, cache.pool, case, values, keep_timeseries, address))
            if streaming:
                unsent.append(result_message(results[-1]))
                if _time.monotonic() - sent >= STREAM_SECONDS:
                    send()
    finally:
        gc.unfreeze()
    return results


def _cancelled(worker: Any) -> bool:
    """Whether the client cancelled the task this thread runs (Dask lets a cancelled task run on
    and drops its result)."""
    try:
        from distributed.worker import thread_state

        task = worker.state.tasks.get(thread_state.key)
        return task is None or task.state == "cancelled"
    except Exception:  # noqa: BLE001 - another Dask's internals: run on, as Dask would
        return False


def result_message(result: CaseResult) -> Dict[str, Any]:
    """A case's result as a Dask event carries it (msgpack's types; no time series, no values: the
    client has them)."""
    return {"case": int(result.case), "metrics": {str(k): float(v) for k, v in result.metrics.items()},
            "status": result.status, "error": result.error, "wall_time": result.wall_time,
            "setup_time": result.setup_time, "sim_time": result.sim_time, "worker": result.worker}


def from_message(message: Mapping[str, Any], values: Dict[str, Any]) -> CaseResult:
    """The :class:`CaseResult` of a :func:`result_message` (``values``: the case's, as the client has them)."""
    return CaseResult(message["case"], dict(values), dict(message["metrics"]), message["status"], message["error"],
                      message["wall_time"], message["setup_time"], message["sim_time"], None, message["worker"])


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()
