"""Our own ctypes binding of the few SUNDIALS 7 functions :mod:`.cvode` calls, loaded so that the
libraries bind to their own symbols, never the host's.

Which libraries: a portable FMU carries SUNDIALS in ``resources/python/sundials/`` (beside its
``deltafmi`` runtime); otherwise the copy that fmpy ships, found without importing fmpy. Nothing
here imports fmpy: an FMU runs in hosts that have numpy and nothing else.

Why ``RTLD_DEEPBIND``: an FMU runs in a process we do not own. A C host that links another
SUNDIALS (Debian's 6.4, as OMSimulator and OpenModelica's runtime do) has ``CVode``,
``cvLsSetup``, ``N_VLinearSum`` ... in the global symbol scope, and the dynamic linker resolves a
library's calls to its *own* exported functions there first: our CVODE 7 would then call the
host's CVODE 6 internals and crash. ``RTLD_DEEPBIND`` puts each library's own scope (itself, then
its dependencies) ahead of the global one, so our solver uses our copies whatever the host has
loaded. It costs nothing per call: it only changes where symbols are looked up at load time.

Messages: SUNDIALS prints warnings on *stdout* and errors on stderr by default; an FMU must print
nothing. :func:`new_context` gives every context a handler that keeps errors for the caller, and
one process-wide logger whose messages go to Python logging (logger ``deltafmi.solver``).
"""
from __future__ import annotations

import ctypes
import importlib.util
import logging
import os
import platform
import sys
from ctypes import POINTER, byref, c_char_p, c_double, c_int, c_int64, c_long, c_void_p
from pathlib import Path
from typing import Any, Callable, Optional

from .errors import DeltaFmiError

__all__ = ["SundialsNotFound", "library_directory", "new_context", "LOGGER", "CV_ADAMS", "CV_BDF", "CV_NORMAL",
           "CV_ROOT_RETURN", "CVode", "CVodeCreate", "CVodeFree", "CVodeGetRootInfo", "CVodeInit", "CVodeReInit",
           "CVodeRootInit", "CVodeSVtolerances", "CVodeSetJacFn", "CVodeSetLinearSolver", "CVodeSetMaxNumSteps",
           "CVodeSetMaxStep", "CVodeSetNoInactiveRootWarn", "CVodeSetProjErrEst", "CVodeSetProjFn",
           "CVodeSetProjFrequency", "CVodeSetStopTime", "CVodeSetUserData", "JacFn", "N_VDestroy", "N_VGetArrayPointer",
           "N_VNew_Serial", "ProjFn", "RhsFn", "SUNContext_Free", "SUNDenseMatrix", "SUNDenseMatrix_Data",
           "SUNLinSolFree", "SUNLinSol_Dense", "SUNMatDestroy"]

#: where SUNDIALS' warnings and errors go (the FMU routes Python logging to the FMI logger)
LOGGER = logging.getLogger("deltafmi.solver")
LOGGER.addHandler(logging.NullHandler())  # no "last resort" printing on stderr when nobody listens

#: in dependency order (each later one needs the earlier ones' sonames)
_NAMES = ("sundials_core", "sundials_nvecserial", "sundials_sunmatrixdense", "sundials_sunlinsoldense",
          "sundials_cvode")
_MODE = ctypes.RTLD_LOCAL | getattr(os, "RTLD_DEEPBIND", 0) | getattr(os, "RTLD_NOW", 2)


class SundialsNotFound(DeltaFmiError, ImportError):
    """Neither the FMU nor an installed fmpy provides the SUNDIALS libraries."""


def _platform() -> tuple[str, str]:
    """(fmpy's platform folder name, shared library suffix) of this machine."""
    machine = platform.machine().lower()
    arch = {"amd64": "x86_64", "x86_64": "x86_64", "arm64": "aarch64", "aarch64": "aarch64"}.get(machine, machine)
    if sys.platform.startswith("win"):
        return f"{arch}-windows", ".dll"
    if sys.platform == "darwin":
        return f"{arch}-darwin", ".dylib"
    return f"{arch}-linux", ".so"


def library_directory() -> Path:
    """The folder holding SUNDIALS' libraries: the FMU's own, the running portable interpreter's,
    else fmpy's installed copy.

    Raises:
        SundialsNotFound: with both places named, when neither has them.
    """
    folder, suffix = _platform()
    bundled = Path(__file__).resolve().parents[2] / "sundials"  # resources/python/sundials in an FMU
    # the interpreter a portable FMU brought (resources/python) carries them too: an FMU of ours run
    # inside it (a unit of a scenario exported as one portable FMU) finds them there
    candidates = [bundled, Path(sys.prefix) / "sundials"]
    spec = importlib.util.find_spec("fmpy")  # locates fmpy without importing it
    if spec is not None and spec.submodule_search_locations:
        candidates.append(Path(list(spec.submodule_search_locations)[0]) / "sundials" / folder)
    for directory in candidates:
        if all((directory / f"{name}{suffix}").is_file() for name in _NAMES):
            return directory
    raise SundialsNotFound(
        "the SUNDIALS libraries (CVODE) were found neither in this FMU "
        f"({bundled}) nor in an installed fmpy ({'not installed' if spec is None else candidates[-1]}); "
        "install fmpy (pip install fmpy) in the Python that runs the FMU, or rebuild the FMU with "
        "`deltafmi build --portable`, which carries them")


def _load() -> dict[str, ctypes.CDLL]:
    directory = library_directory()
    suffix = _platform()[1]
    return {name: ctypes.CDLL(str(directory / f"{name}{suffix}"), mode=_MODE) for name in _NAMES}


LIBRARIES = _load()


def _function(library: str, name: str, argtypes: list, restype: Any = c_int) -> Callable:
    # a private function object: indexing does not share a cached one (and its argtypes) with
    # any other binding of the same library in this process
    function = LIBRARIES[library][name]
    function.argtypes, function.restype = argtypes, restype
    return function


# --- types (SUNDIALS 7: sunrealtype double, sunindextype int64, SUNComm int without MPI) -------
SUN_COMM_NULL = 0
#: void (*)(int line, const char* func, const char* file, const char* msg, SUNErrCode, void* user, SUNContext)
ErrHandlerFn = ctypes.CFUNCTYPE(None, c_int, c_char_p, c_char_p, c_char_p, c_int, c_void_p, c_void_p)
#: int (*)(sunrealtype t, N_Vector y, N_Vector ydot, void* user_data); also CVRootFn's shape
RhsFn = ctypes.CFUNCTYPE(c_int, c_double, c_void_p, c_void_p, c_void_p)
#: int (*)(t, y, corr, epsProj, err, user_data)
ProjFn = ctypes.CFUNCTYPE(c_int, c_double, c_void_p, c_void_p, c_double, c_void_p, c_void_p)
#: int (*)(t, y, fy, SUNMatrix J, user_data, tmp1, tmp2, tmp3)
JacFn = ctypes.CFUNCTYPE(c_int, c_double, c_void_p, c_void_p, c_void_p, c_void_p, c_void_p, c_void_p, c_void_p)

CV_ADAMS, CV_BDF = 1, 2
CV_NORMAL = 1
CV_ROOT_RETURN = 2

# --- core -----------------------------------------------------------------------------------
SUNContext_Create = _function("sundials_core", "SUNContext_Create", [c_int, POINTER(c_void_p)])
SUNContext_Free = _function("sundials_core", "SUNContext_Free", [POINTER(c_void_p)])
SUNContext_ClearErrHandlers = _function("sundials_core", "SUNContext_ClearErrHandlers", [c_void_p])
SUNContext_PushErrHandler = _function("sundials_core", "SUNContext_PushErrHandler",
                                      [c_void_p, ErrHandlerFn, c_void_p])
SUNContext_SetLogger = _function("sundials_core", "SUNContext_SetLogger", [c_void_p, c_void_p])
SUNLogger_Create = _function("sundials_core", "SUNLogger_Create", [c_int, c_int, POINTER(c_void_p)])
SUNLogger_SetWarningFilename = _function("sundials_core", "SUNLogger_SetWarningFilename", [c_void_p, c_char_p])
SUNLogger_SetErrorFilename = _function("sundials_core", "SUNLogger_SetErrorFilename", [c_void_p, c_char_p])
N_VGetArrayPointer = _function("sundials_core", "N_VGetArrayPointer", [c_void_p], POINTER(c_double))
N_VDestroy = _function("sundials_core", "N_VDestroy", [c_void_p], None)
SUNMatDestroy = _function("sundials_core", "SUNMatDestroy", [c_void_p], None)
SUNLinSolFree = _function("sundials_core", "SUNLinSolFree", [c_void_p])

# --- vectors, dense matrix, dense linear solver ---------------------------------------------
N_VNew_Serial = _function("sundials_nvecserial", "N_VNew_Serial", [c_int64, c_void_p], c_void_p)
SUNDenseMatrix = _function("sundials_sunmatrixdense", "SUNDenseMatrix", [c_int64, c_int64, c_void_p], c_void_p)
SUNDenseMatrix_Data = _function("sundials_sunmatrixdense", "SUNDenseMatrix_Data", [c_void_p], POINTER(c_double))
SUNLinSol_Dense = _function("sundials_sunlinsoldense", "SUNLinSol_Dense", [c_void_p, c_void_p, c_void_p], c_void_p)

# --- CVODE ----------------------------------------------------------------------------------
CVodeCreate = _function("sundials_cvode", "CVodeCreate", [c_int, c_void_p], c_void_p)
CVodeInit = _function("sundials_cvode", "CVodeInit", [c_void_p, RhsFn, c_double, c_void_p])
CVodeReInit = _function("sundials_cvode", "CVodeReInit", [c_void_p, c_double, c_void_p])
CVodeSVtolerances = _function("sundials_cvode", "CVodeSVtolerances", [c_void_p, c_double, c_void_p])
CVodeRootInit = _function("sundials_cvode", "CVodeRootInit", [c_void_p, c_int, RhsFn])
CVodeSetNoInactiveRootWarn = _function("sundials_cvode", "CVodeSetNoInactiveRootWarn", [c_void_p])
CVodeSetUserData = _function("sundials_cvode", "CVodeSetUserData", [c_void_p, c_void_p])
CVodeSetLinearSolver = _function("sundials_cvode", "CVodeSetLinearSolver", [c_void_p, c_void_p, c_void_p])
CVodeSetJacFn = _function("sundials_cvode", "CVodeSetJacFn", [c_void_p, JacFn])
CVodeSetMaxStep = _function("sundials_cvode", "CVodeSetMaxStep", [c_void_p, c_double])
CVodeSetMaxNumSteps = _function("sundials_cvode", "CVodeSetMaxNumSteps", [c_void_p, c_long])
CVodeSetStopTime = _function("sundials_cvode", "CVodeSetStopTime", [c_void_p, c_double])
CVodeSetProjFn = _function("sundials_cvode", "CVodeSetProjFn", [c_void_p, ProjFn])
CVodeSetProjErrEst = _function("sundials_cvode", "CVodeSetProjErrEst", [c_void_p, c_int])
CVodeSetProjFrequency = _function("sundials_cvode", "CVodeSetProjFrequency", [c_void_p, c_long])
CVode = _function("sundials_cvode", "CVode", [c_void_p, c_double, c_void_p, POINTER(c_double), c_int])
CVodeGetRootInfo = _function("sundials_cvode", "CVodeGetRootInfo", [c_void_p, POINTER(c_int)])
CVodeFree = _function("sundials_cvode", "CVodeFree", [POINTER(c_void_p)], None)


# --- messages -------------------------------------------------------------------------------
# SUNDIALS 7 has no public setter for a logger's message function. Its logger (struct SUNLogger_
# of src/sundials/sundials_logger_impl.h, unchanged through 7.x) is: int comm, int output_rank,
# FILE* debug/warning/info/error, hashmap, format, content, then the queuemsg function pointer.
# We write that pointer into a logger we created ourselves, after checking the fields that
# SUNLogger_Create sets to known values; if they do not match, warnings are discarded instead.
_QueueMsgFn = ctypes.CFUNCTYPE(c_int, c_void_p, c_int, c_char_p, c_char_p, c_char_p, c_void_p)
_SUN_LOGLEVEL = {1: logging.ERROR, 2: logging.WARNING, 3: logging.INFO, 4: logging.DEBUG}


def _libc() -> Optional[ctypes.CDLL]:
    try:
        return ctypes.CDLL(None)
    except OSError:
        return None


_LIBC = _libc()
_vsnprintf = getattr(_LIBC, "vsnprintf", None)
if _vsnprintf is not None:
    _vsnprintf.argtypes, _vsnprintf.restype = [c_char_p, ctypes.c_size_t, c_char_p, c_void_p], c_int


def _queue_message(_logger: int, level: int, scope: bytes, label: bytes, text: bytes, args: int) -> int:
    # va_list arrives as a pointer (x86_64 and aarch64 Linux, Windows, macOS alike)
    try:
        message = text or b""
        if _vsnprintf is not None and b"%" in message:
            buffer = ctypes.create_string_buffer(2048)
            _vsnprintf(buffer, len(buffer), message, args)
            message = buffer.value
        LOGGER.log(_SUN_LOGLEVEL.get(level, logging.WARNING), "%s: %s", (label or b"SUNDIALS").decode(errors="replace"),
                   message.decode(errors="replace"))
    except Exception:  # noqa: BLE001  (never let an exception cross into C)
        pass
    return 0


_QUEUE_MESSAGE = _QueueMsgFn(_queue_message)


def _stdio(name: str) -> Optional[int]:
    try:
        return c_void_p.in_dll(_LIBC, name).value if _LIBC is not None else None
    except ValueError:
        return None


def _make_logger() -> tuple[int, bool]:
    """A process-wide logger for every context: (address, True if it reaches Python logging)."""
    logger = c_void_p()
    if SUNLogger_Create(SUN_COMM_NULL, 0, byref(logger)) != 0 or not logger.value:
        raise OSError("SUNLogger_Create failed")
    words = (c_void_p * 11).from_address(logger.value)  # 8 + 10 pointers = 88 bytes
    fields = [words[k] for k in range(11)]
    stdout, stderr = _stdio("stdout"), _stdio("stderr")
    if (fields[0] is None and stdout is not None and stderr is not None and fields[1] is None
            and fields[2] == stdout and fields[3] is None and fields[4] == stderr and fields[5]
            and all(f is None for f in fields[7:11])):
        words[8] = ctypes.cast(_QUEUE_MESSAGE, c_void_p).value
        return logger.value, True
    # an unknown layout: do not touch it, send its output nowhere
    SUNLogger_SetWarningFilename(logger, os.devnull.encode())
    SUNLogger_SetErrorFilename(logger, os.devnull.encode())
    return logger.value, False


#: never destroyed: contexts of solvers that outlive this module's users still point to it
_LOGGER_ADDRESS, ROUTED = _make_logger()


def new_context(on_error: Callable[[int, bytes, bytes, bytes, int], None]) -> tuple[c_void_p, object]:
    """A SUNContext whose messages never reach stdout or stderr.

    ``on_error(line, function, file, message, code)`` receives every error (instead of SUNDIALS'
    default handler, which prints it); warnings go to :data:`LOGGER`. Returns the context and the
    ctypes callback, which the caller keeps referenced as long as the context lives.
    """
    context = c_void_p()
    flag = SUNContext_Create(SUN_COMM_NULL, byref(context))
    if flag != 0:
        raise OSError(f"SUNContext_Create failed with flag {flag}")
    handler = ErrHandlerFn(lambda line, function, file, message, code, _user, _ctx:
                           on_error(line, function, file, message, code))
    SUNContext_ClearErrHandlers(context)
    SUNContext_PushErrHandler(context, handler, None)
    SUNContext_SetLogger(context, _LOGGER_ADDRESS)
    return context, handler
