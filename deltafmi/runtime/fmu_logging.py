"""An FMU's Python code speaks through the importer's FMI logger, and only there.

While the native bridge runs an FMU instance's Python code on a thread, it puts that instance's
message list in the thread's *slot* (``log_slots[thread id][0]``, in the process-wide registry
module that every deltafmi FMU shares), and drains the list into ``fmi2CallbackLogger`` when the
call returns. Two process-wide hooks, installed once by the first FMU instance, fill it:

- ``logging.Logger.callHandlers``: a record of any logger (the model's
  ``logging.getLogger(__name__)``, also ``Component.logger``; ``deltafmi.solver``; a library's)
  logged while FMU code runs on this thread goes to that instance instead of to handlers;
- ``warnings.showwarning``: a warning raised while FMU code runs goes to that instance.

Outside FMU calls both hooks hand over to what was there before: the host's handlers, levels,
``basicConfig``, ``lastResort`` and warning display stay as the host set them. Threads are told
apart by their slot: two instances stepped from two threads never see each other's messages. A
message is ``(status, category, text)``; the loader filters them by the categories the importer
enabled (fmi2SetDebugLogging) and always passes errors. Python's warning filters still decide
which warnings are raised at all (by default one per code location and process).
"""
from __future__ import annotations

import logging
import sys
import threading
import traceback
import types
import warnings
from typing import Any, Optional

__all__ = ["BITS", "CATEGORIES", "DEFAULT", "LOG_ALL", "MODEL_MODULE_PREFIX", "hooks", "message"]

OK, WARNING, DISCARD, ERROR = 0, 1, 2, 3

#: the FMU's <LogCategories>, in the bit order the loader uses (native/core.c CATEGORY_NAMES);
#: ``logAll`` is a name for all of them in fmi2SetDebugLogging, not a category of its own
CATEGORIES = (
    ("logEvents", "Events, event iterations and the end of the simulation (status OK)"),
    ("logComponent", "The component's DEBUG and INFO logging records and Component.log('info') (status OK)"),
    ("logSolver", "The Co-Simulation solver: CVODE set-up and informational messages (status OK)"),
    ("logStatusWarning", "Warnings: logging WARNING records, warnings.warn, solver warnings (fmi2Warning)"),
    ("logStatusDiscard", "Why a step was discarded or the component ended the simulation (fmi2Discard)"),
    ("logStatusError", "Errors: logging ERROR records, Python exceptions with tracebacks (fmi2Error; "
                       "always sent)"),
)
LOG_ALL = ("logAll", "Every category above")
BITS = {name: 1 << i for i, (name, _) in enumerate(CATEGORIES)}
ALL = (1 << len(CATEGORIES)) - 1
#: what an instance sends when instantiated with loggingOn = false
DEFAULT = BITS["logStatusWarning"] | BITS["logStatusDiscard"] | BITS["logStatusError"]

_REGISTRY_NAME = "_deltafmi_fmu_registry"
_KEY = "log_dispatch_v1"  # bump when the slot protocol changes
MODEL_MODULE_PREFIX = "_deltafmi_fmu_"  # boot.py imports every FMU model under such a name
SOLVER_LOGGER = "deltafmi.solver"


def registry() -> types.ModuleType:
    """The module every deltafmi FMU in this process shares (created by the FMU's boot code)."""
    return sys.modules.setdefault(_REGISTRY_NAME, types.ModuleType(_REGISTRY_NAME))


def message(record: logging.LogRecord) -> tuple:
    """``(status, category, text)`` of a logging record: ERROR and above fmi2Error, WARNING
    fmi2Warning, lower levels OK in logSolver (the solver's logger) or logComponent."""
    try:
        text = record.getMessage()
    except Exception as exc:  # noqa: BLE001  (a bad format string must not break the step)
        text = f"{record.msg!r} (unformattable: {exc})"
    if record.exc_info:
        text += "\n" + "".join(traceback.format_exception(*record.exc_info)).rstrip()
    name = record.name
    if name != "root" and not name.startswith(MODEL_MODULE_PREFIX):
        text = f"{name}: {text}"
    if record.levelno >= logging.ERROR:
        return ERROR, "logStatusError", text
    if record.levelno >= logging.WARNING:
        return WARNING, "logStatusWarning", text
    solver = name == SOLVER_LOGGER or name.startswith(SOLVER_LOGGER + ".")
    return OK, "logSolver" if solver else "logComponent", text


class _Hooks:
    """The process-wide hooks (one set per process, shared by every FMU of this protocol)."""

    def __init__(self) -> None:
        self.slots: dict = registry().__dict__.setdefault("log_slots", {})
        self.original_call_handlers = logging.Logger.callHandlers
        self.previous_showwarning = warnings.showwarning
        self.debug_wanted: dict = {}  # model logger name -> {instance id: wants DEBUG/INFO records}
        self.lock = threading.Lock()
        logging.Logger.callHandlers = self._call_handlers()  # type: ignore[method-assign]
        warnings.showwarning = self.showwarning  # type: ignore[assignment]

    def sink(self) -> Optional[list]:
        """The message list of the FMU instance whose code runs on this thread, or None."""
        slot = self.slots.get(threading.get_ident())
        return slot[0] if slot else None

    def _call_handlers(self) -> Any:
        original, sink = self.original_call_handlers, self.sink

        def call_handlers(logger: logging.Logger, record: logging.LogRecord) -> None:
            """Logger.callHandlers: to the running FMU instance, else to the logger's handlers."""
            into = sink()
            if into is None:
                original(logger, record)
                return
            try:
                into.append(message(record))
            except Exception:  # noqa: BLE001  (logging must never raise into the model, nor print)
                pass

        return call_handlers

    def showwarning(self, message_: Any, category: type, filename: str, lineno: int, file: Any = None,
                    line: Optional[str] = None) -> None:
        """warnings.showwarning: to the running FMU instance, else to the previous hook."""
        sink = self.sink() if file is None else None
        if sink is None:
            self.previous_showwarning(message_, category, filename, lineno, file, line)
            return
        where = str(filename)
        inside = where.rfind("/resources/")  # the FMU's own files: the path inside the FMU
        if inside >= 0:
            where = where[inside + 1:]
        sink.append((WARNING, "logStatusWarning", f"{where}:{lineno}: {category.__name__}: {message_}"))

    def adopt(self, module_name: str) -> None:
        """Let the model module's logger make DEBUG and INFO records while a new instance is made
        (its setup() may log before the loader tells it the categories, see :meth:`want_debug`)."""
        with self.lock:
            self.debug_wanted.setdefault(module_name, {})
            logging.getLogger(module_name).setLevel(logging.DEBUG)

    def want_debug(self, module_name: str, instance: int, wanted: Optional[bool]) -> None:
        """Record whether an instance wants its component's DEBUG/INFO records (None: it is gone);
        the model's logger creates them only while some instance does."""
        with self.lock:
            wants = self.debug_wanted.setdefault(module_name, {})
            if wanted is None:
                wants.pop(instance, None)
            else:
                wants[instance] = wanted
            level = logging.DEBUG if any(wants.values()) else logging.WARNING
        logging.getLogger(module_name).setLevel(level)


def exception_report(context: str, kind: Any, value: Any, tb: Any) -> str:
    """The logStatusError message of an exception the FMU's Python code raised in ``context`` (the
    bridge's name of the FMI call): the traceback, its last line (the one importers quote) ending
    with the model's own source line, the innermost frame in ``resources/model/``:
    "RuntimeError: my bug (trajectory.py:96 in outputs)". The bridge calls it through the registry."""
    text = "".join(traceback.format_exception(kind, value, tb)).rstrip()
    where = None
    while tb is not None:
        code = tb.tb_frame.f_code
        path = code.co_filename.replace("\\", "/")
        inside = path.rfind(_MODEL_DIR)
        if inside >= 0:
            where = f"{path[inside + len(_MODEL_DIR):]}:{tb.tb_lineno} in {code.co_name}"
        tb = tb.tb_next
    return f"{context}: Python exception\n{text}" + (f" ({where})" if where else "")


_MODEL_DIR = "/resources/model/"  # where an FMU keeps the model's source (export/packager.py)


def hooks() -> Any:
    """Install the process-wide hooks once (whichever FMU's runtime comes first) and return them."""
    shared = registry().__dict__
    found = shared.get(_KEY)
    shared.setdefault("exception_report_v1", exception_report)  # what the bridge formats exceptions with
    if found is None:
        lock = shared.setdefault("log_lock", threading.Lock())
        with lock:
            found = shared.get(_KEY)
            if found is None:
                found = shared[_KEY] = _Hooks()
    return found
