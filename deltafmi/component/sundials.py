"""fmpy's SUNDIALS libraries, loaded so that they bind to their own symbols, never the host's.

An FMU runs in a process we do not own. A C host that links another SUNDIALS (Debian's 6.4, as
OMSimulator and OpenModelica's runtime do) has ``CVode``, ``cvLsSetup``, ``N_VLinearSum`` ... in the
global symbol scope, and the dynamic linker resolves a library's calls to its *own* exported
functions there first: fmpy's CVODE 7 would then call the host's CVODE 6 internals and crash.
``RTLD_DEEPBIND`` puts each library's own scope (itself, then its dependencies) ahead of the
global one, so our solver uses our copies whatever the host has loaded. The binding is fixed when
a library is first loaded, so this module must load them before ``fmpy.sundials`` does (importing
it does: the later ``cdll.LoadLibrary`` calls of fmpy get the same, already bound, objects).

It costs nothing per call: DEEPBIND only changes where symbols are looked up at load time.
"""
from __future__ import annotations

import ctypes
import os
from ctypes import POINTER, c_int, c_void_p
from pathlib import Path

import fmpy

#: in dependency order, as fmpy loads them (each later one needs the earlier ones' sonames)
_NAMES = ("sundials_core", "sundials_nvecserial", "sundials_sunmatrixdense", "sundials_sunlinsoldense",
          "sundials_cvode")
_MODE = ctypes.RTLD_LOCAL | getattr(os, "RTLD_DEEPBIND", 0) | getattr(os, "RTLD_NOW", 2)


def _load() -> dict:
    directory = Path(fmpy.__file__).parent / "sundials" / fmpy.platform_tuple
    return {name: ctypes.CDLL(str(directory / f"{name}{fmpy.sharedLibraryExtension}"), mode=_MODE)
            for name in _NAMES}


LIBRARIES = _load()
core = LIBRARIES["sundials_core"]
cvode = LIBRARIES["sundials_cvode"]


def _function(library: ctypes.CDLL, name: str, argtypes: list, restype=c_int):
    # a private function object: fmpy's cached one may carry other argtypes
    function = library[name]
    function.argtypes, function.restype = argtypes, restype
    return function


# destructors fmpy does not bind
N_VDestroy = _function(core, "N_VDestroy", [c_void_p], None)
SUNMatDestroy = _function(core, "SUNMatDestroy", [c_void_p], None)
SUNLinSolFree = _function(core, "SUNLinSolFree", [c_void_p])
SUNContext_Free = _function(core, "SUNContext_Free", [POINTER(c_void_p)])
SUNContext_ClearErrHandlers = _function(core, "SUNContext_ClearErrHandlers", [c_void_p])
