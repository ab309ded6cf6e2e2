"""Loaded FMUs kept across runs: each case after the first resets its instances (``fmi2Reset``)
instead of loading, extracting and instantiating them again.

A :class:`FmuPool` lends fmpy FMU objects to the master (``Master(fmus=pool.lend)``). A pooled
object is an ordinary ``FMU2Slave`` / ``FMU2Model`` (FMI 3.0: ``FMU3Slave`` / ``FMU3Model``) whose
``instantiate`` instantiates the first time and calls ``fmi2Reset`` / ``fmi3Reset`` afterwards (the
FMU is then as if just instantiated), and whose ``freeInstance`` gives it back to the pool instead
of freeing it. The FMU keeps the logger it got when instantiated until it is freed, so the pool
hands it a logger of its own that forwards every message to the logger of whoever holds the FMU
now. Instances of a run that failed are freed (:meth:`FmuPool.discard`): a case that went
wrong leaves nothing behind.

An instance whose FMU can get and set its state (FMI 2.0 or 3.0) also keeps its last few distinct
initializations (:mod:`deltafmi.apps.studies.snapshots`): a case that initializes it exactly as
an earlier case did gets it from an FMU state snapshot instead of reset and initialized again.
"""
from __future__ import annotations

import shutil
import tempfile
import threading
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Tuple

import fmpy
from fmpy.fmi2 import (FMU2Model, FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)
from fmpy.fmi3 import FMU3Model, FMU3Slave

from deltafmi.master.scenario.system import ResolvedComponent

from .snapshots import RECORDED_CALLS, RECORDED_CALLS3, InitTranscript, Prefixes, Replay

__all__ = ["FmuPool"]

Key = Tuple[str, str, str]  # FMU file, interface, instance name

#: initializations kept per pooled instance (an FMU state each): a study's grid repeats each value
#: of a unit's parameters in many cases, rarely one after the other
KEEP = 32


class _Pooled:
    """What the pooled FMU classes add to fmpy's: instantiate once, reset afterwards."""

    #: the ``instantiate`` argument that carries the holder's logger
    logger_argument = "callbacks"

    def __init__(self, pool: "FmuPool", key: Key, **kwargs: Any) -> None:
        super().__init__(**kwargs)  # type: ignore[call-arg]
        self.pool, self.key = pool, key
        self.resets = 0
        self._holder: Any = None
        self._own: Any = None

    def instantiate(self, **kwargs: Any) -> None:
        """Instantiate the first time, reset afterwards; messages go to the holder's logger."""
        self._holder = kwargs.pop(self.logger_argument, None)
        if self.component is None:  # type: ignore[attr-defined,has-type]
            self._own = kwargs[self.logger_argument] = self._forwarder()
            super().instantiate(**kwargs)  # type: ignore[misc]
        else:
            self.reset()  # type: ignore[attr-defined]
            self.resets += 1

    def freeInstance(self) -> None:
        """Give the instance back to the pool (it stays instantiated)."""
        self._holder = None
        self.pool.give_back(self)

    def free(self) -> None:
        """Free the instance for real (and unload the library, as fmpy does)."""
        self._holder = None
        if self.component is not None:  # type: ignore[attr-defined,has-type]
            try:
                super().freeInstance()  # type: ignore[misc]
            finally:
                self.component = None

    def _forwarder(self) -> Any:
        raise NotImplementedError


class _Snapshotting(_Pooled):
    """Instantiate once, reset afterwards, and an initialization that repeats one of the last ones
    restored from its snapshot (see :mod:`deltafmi.apps.studies.snapshots`)."""

    #: the fmpy methods that get, set and free an FMU state
    get_state, set_state, free_state = "getFMUstate", "setFMUstate", "freeFMUstate"

    def __init__(self, pool: "FmuPool", key: Key, **kwargs: Any) -> None:
        super().__init__(pool, key, **kwargs)
        #: take snapshots (the FMU can get and set its state, and the pool wants them)
        self.snapshots = False
        #: initializations restored from a snapshot
        self.restores = 0
        self._kept: List[InitTranscript] = []  # the last initializations with their snapshots, latest used first
        self._prefixes = Prefixes(())  # the calls of _kept as one tree
        self._new: Optional[InitTranscript] = None  # the initialization under way, being recorded
        self._replay: Optional[Replay] = None  # the initialization under way, checked against _kept
        self._terminate_due = False  # terminate held back (see terminate)

    def instantiate(self, **kwargs: Any) -> None:
        """As :meth:`_Pooled.instantiate`; with snapshots kept, the reset waits for the first call
        that differs from every kept initialization."""
        self._new = self._replay = None
        if self.component is not None and self._kept:
            self._holder = kwargs.pop(self.logger_argument, None)
            self._replay = Replay(self._prefixes)
            return
        self._terminate_now()
        super().instantiate(**kwargs)
        if self.snapshots:
            self._new = InitTranscript()

    def _through(self, name: str, args: Tuple[Any, ...], kwargs: Dict[str, Any]) -> Any:
        """A call of :data:`RECORDED_CALLS`: answered from a kept initialization while one matches,
        else made (and recorded while initializing)."""
        replay = self._replay
        if replay is not None:
            call = replay.next(name, args, kwargs)
            if call is not None:
                if name == "exitInitializationMode":
                    self._restore(replay.transcript)
                return list(call.result) if isinstance(call.result, list) else call.result
            self._make_real()
        elif self._terminate_due:  # a call after terminate, before the next case's
            self._terminate_now()
        live = getattr(super(_Snapshotting, self), name)
        new = self._new
        if new is None:
            return live(*args, **kwargs)
        try:
            result = new.record(name, args, kwargs, live)
        except BaseException:
            self._new = None
            raise
        if name == "exitInitializationMode":
            self._new = None
            self._keep(new)
        return result

    def terminate(self) -> Any:
        """Terminate, held back while the instance keeps snapshots: made before any other call of
        the FMU and before the instance is freed, and left out when the next case sets the FMU to
        a snapshot. An FMU state carries the state machine's place (ours does), but an FMU that
        restores only its variables would stay terminated after the restore and refuse to step."""
        if not self.snapshots:
            self._unrecorded()
            return super().terminate()  # type: ignore[misc]
        self._terminate_due = True
        return 0

    def _terminate_now(self) -> None:
        """The terminate held back, if any."""
        if self._terminate_due:
            self._terminate_due = False
            super().terminate()  # type: ignore[misc]

    def _unrecorded(self) -> None:
        """Before any other FMI call: the FMU must be real, and an initialization that made such a
        call is not kept."""
        self._terminate_now()
        if self._replay is not None:
            self._make_real()
        self._new = None

    def _make_real(self) -> None:
        """The case differs from every kept initialization: reset, and make the calls that matched."""
        assert self._replay is not None
        matched, self._replay = self._replay.matched(), None
        self._terminate_now()
        self.reset()  # type: ignore[attr-defined]
        self.resets += 1
        new = self._new = InitTranscript()
        for call in matched:
            new.record(call.name, call.args, call.kwargs, getattr(super(_Snapshotting, self), call.name))

    def _restore(self, transcript: InitTranscript) -> None:
        """The initialization repeats a kept one: set the FMU to its snapshot (which puts it back
        in the state machine's state it was taken in: after fmi2Terminate, too)."""
        self._replay = None
        self._terminate_due = False  # the snapshot replaces what terminate would have done
        getattr(super(), self.set_state)(transcript.state)
        self.restores += 1
        self.pool.restored += 1
        if self._kept[0] is not transcript:
            self._kept.remove(transcript)
            self._kept.insert(0, transcript)
        for message in transcript.messages:
            self._forward(*message)

    def _keep(self, transcript: InitTranscript) -> None:
        """Initialization done: its snapshot joins the kept ones (none if the FMU cannot give it),
        the least recently used dropped beyond the pool's limit."""
        try:
            transcript.state = getattr(super(), self.get_state)()
        except Exception:  # noqa: BLE001 - no snapshot: the next case initializes as usual
            return
        self._kept.insert(0, transcript)
        while len(self._kept) > self.pool.keep:
            self._free_state(self._kept.pop())
        self._prefixes = Prefixes(self._kept)

    def _free_state(self, transcript: InitTranscript) -> None:
        if transcript.state is not None and self.component is not None:
            try:
                getattr(super(), self.free_state)(transcript.state)
            except Exception:  # noqa: BLE001 - the instance is going anyway
                pass

    def free(self) -> None:
        """Free the snapshots, then the instance."""
        self._replay = self._new = None
        try:
            self._terminate_now()
        except Exception:  # noqa: BLE001 - freed anyway
            pass
        kept, self._kept = self._kept, []
        self._prefixes = Prefixes(())
        for transcript in kept:
            self._free_state(transcript)
        super().free()

    def _recording(self, message: Tuple[Any, ...]) -> None:
        if self._new is not None:
            self._new.messages.append(message)


class _Pooled2(_Snapshotting):
    """FMI 2.0: the logger callbacks of :class:`_Snapshotting`."""

    def _forwarder(self) -> fmi2CallbackFunctions:
        from fmpy import calloc, free

        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(self._forward)
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        return callbacks

    def _forward(self, env: Any, instance: Any, status: int, category: Any, message: Any) -> None:
        self._recording((env, instance, status, category, message))
        holder = self._holder
        if holder is not None and holder.logger:
            holder.logger(env, instance, status, category, message)


class _Pooled3(_Snapshotting):
    """FMI 3.0: the log message callback of :class:`_Snapshotting`."""

    logger_argument = "logMessage"
    get_state, set_state, free_state = "getFMUState", "setFMUState", "freeFMUState"

    def _forwarder(self) -> Callable[..., None]:
        return self._forward  # fmpy wraps it in an fmi3LogMessageCallback and keeps that

    def _forward(self, env: Any, status: int, category: Any, message: Any) -> None:
        self._recording((env, status, category, message))
        holder = self._holder
        if holder is not None:
            holder(env, status, category, message)


def _recorded(name: str) -> Callable[..., Any]:
    def method(self: _Snapshotting, *args: Any, **kwargs: Any) -> Any:
        return self._through(name, args, kwargs)
    method.__name__ = name
    return method


def _unrecorded(name: str) -> Callable[..., Any]:
    def method(self: _Snapshotting, *args: Any, **kwargs: Any) -> Any:
        self._unrecorded()
        return getattr(super(_Snapshotting, self), name)(*args, **kwargs)
    method.__name__ = name
    return method


#: fmpy methods that neither change an instance nor depend on its state (or that the pool makes itself)
_UNWRAPPED = frozenset({"instantiate", "freeInstance", "freeLibrary", "reset", "getVersion", "getTypesPlatform",
                        "getNumberOfContinuousStates", "getNumberOfEventIndicators",
                        "getNumberOfVariableDependencies", "getVariableDependencies"})


def _wrap(cls: type, recorded: Tuple[str, ...], *fmpy_classes: type) -> None:
    """Every other fmpy call on an instance of ``cls``: the FMU made real first (and the
    initialization under way not kept), whatever the master calls."""
    for name in recorded:
        setattr(cls, name, _recorded(name))
    names = {name for fmpy_class in fmpy_classes for base in fmpy_class.__mro__ for name, value in vars(base).items()
             if callable(value) and name[:1].islower() and not name.startswith("fmi")}  # fmi*: the C functions
    for name in sorted(names - set(recorded) - _UNWRAPPED - {"terminate"}):  # terminate: _Snapshotting's
        setattr(cls, name, _unrecorded(name))


_wrap(_Pooled2, RECORDED_CALLS, FMU2Slave, FMU2Model)
_wrap(_Pooled3, RECORDED_CALLS3, FMU3Slave, FMU3Model)


# fmpy binds the fmi2 functions of classes whose name starts with "FMU2"
class FMU2PooledSlave(_Pooled2, FMU2Slave):
    """A Co-Simulation FMU that resets instead of re-instantiating."""


class FMU2PooledModel(_Pooled2, FMU2Model):
    """A Model Exchange FMU that resets instead of re-instantiating."""


class FMU3PooledSlave(_Pooled3, FMU3Slave):
    """An FMI 3.0 Co-Simulation FMU that resets instead of re-instantiating."""


class FMU3PooledModel(_Pooled3, FMU3Model):
    """An FMI 3.0 Model Exchange FMU that resets instead of re-instantiating."""


_CLASSES = {(False, "CS"): FMU2PooledSlave, (False, "ME"): FMU2PooledModel,
            (True, "CS"): FMU3PooledSlave, (True, "ME"): FMU3PooledModel}


class FmuPool:
    """Idle loaded FMUs by (FMU file, interface, instance name); thread-safe.

    Each FMU file is extracted once under ``root``: a temporary folder by default, made at the
    first extraction and removed by :meth:`close`.
    """

    def __init__(self, root: Optional[Path] = None, snapshots: bool = True, keep: int = KEEP) -> None:
        """``snapshots``: instances whose FMU can get and set its state restore an initialization
        that repeats one of their last ``keep`` from a snapshot (:mod:`.snapshots`)."""
        self.snapshots = snapshots
        self.keep = keep
        self._own_root = root is None
        self._root: Optional[Path] = None if root is None else Path(root)
        self._idle: Dict[Key, List[_Pooled]] = {}
        self._extracted: Dict[str, str] = {}
        self._lock = threading.Lock()
        self._extractions = 0
        self.created = 0
        #: initializations restored from a snapshot (all instances, since the pool was made)
        self.restored = 0

    @property
    def root(self) -> Path:
        """The folder the FMUs are extracted in (a temporary one is made when first needed)."""
        if self._root is None:
            self._root = Path(tempfile.mkdtemp(prefix="deltafmi-pool-"))
        return self._root

    def lend(self, component: ResolvedComponent) -> _Pooled:
        """An FMU object for ``component``: an idle one (to be reset), else a new one."""
        key = (str(component.fmu), component.interface, component.name)
        with self._lock:
            idle = self._idle.get(key)
            if idle:
                return idle.pop()
            directory = self._extracted.get(key[0])
            if directory is None:
                # a counter, not len(): a folder of a forgotten FMU may not be reused by another
                target = self.root / f"{self._extractions}-{Path(key[0]).stem}"
                self._extractions += 1
                directory = self._extracted[key[0]] = fmpy.extract(key[0], unzipdir=str(target))
            cls = _CLASSES[component.info.fmi3, component.interface]
            self.created += 1
            fmu = cls(self, key, guid=component.info.md.guid, unzipDirectory=directory,
                      modelIdentifier=component.info.model_identifier(component.interface),
                      instanceName=component.name)
            fmu.snapshots = self.snapshots and component.info.can_get_set_state(component.interface)
            return fmu

    def give_back(self, fmu: _Pooled) -> None:
        """Make ``fmu`` available again (called by its ``freeInstance``)."""
        with self._lock:
            idle = self._idle.setdefault(fmu.key, [])
            if fmu not in idle:
                idle.append(fmu)

    def discard(self, fmus: List[_Pooled]) -> None:
        """Free ``fmus`` for good (their run failed: the next run instantiates afresh)."""
        for fmu in fmus:
            with self._lock:
                idle = self._idle.get(fmu.key, [])
                if fmu in idle:
                    idle.remove(fmu)
            try:
                fmu.free()
            except Exception:  # noqa: BLE001 - a broken instance must not stop the study
                pass

    def forget(self, fmu_file: str) -> None:
        """Free every idle instance of ``fmu_file`` and remove its extraction."""
        with self._lock:
            keys = [k for k in self._idle if k[0] == fmu_file]
            doomed = [f for k in keys for f in self._idle.pop(k)]
            directory = self._extracted.pop(fmu_file, None)
        self.discard(doomed)
        if directory:
            shutil.rmtree(directory, ignore_errors=True)

    def close(self) -> None:
        """Free every idle instance and the extracted files."""
        for fmu_file in list(self._extracted):
            self.forget(fmu_file)
        with self._lock:
            root, self._root = self._root, (None if self._own_root else self._root)
        if self._own_root and root is not None:
            shutil.rmtree(root, ignore_errors=True)
