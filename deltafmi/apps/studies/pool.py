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

__all__ = ["FmuPool"]

Key = Tuple[str, str, str]  # FMU file, interface, instance name


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


class _Pooled2(_Pooled):
    def _forwarder(self) -> fmi2CallbackFunctions:
        from fmpy import calloc, free

        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(self._forward)
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        return callbacks

    def _forward(self, env: Any, instance: Any, status: int, category: Any, message: Any) -> None:
        holder = self._holder
        if holder is not None and holder.logger:
            holder.logger(env, instance, status, category, message)


class _Pooled3(_Pooled):
    logger_argument = "logMessage"

    def _forwarder(self) -> Callable[..., None]:
        return self._forward  # fmpy wraps it in an fmi3LogMessageCallback and keeps that

    def _forward(self, env: Any, status: int, category: Any, message: Any) -> None:
        holder = self._holder
        if holder is not None:
            holder(env, status, category, message)


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

    def __init__(self, root: Optional[Path] = None) -> None:
        self._own_root = root is None
        self._root: Optional[Path] = None if root is None else Path(root)
        self._idle: Dict[Key, List[_Pooled]] = {}
        self._extracted: Dict[str, str] = {}
        self._lock = threading.Lock()
        self._extractions = 0
        self.created = 0

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
            return cls(self, key, guid=component.info.md.guid, unzipDirectory=directory,
                       modelIdentifier=component.info.model_identifier(component.interface),
                       instanceName=component.name)

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
