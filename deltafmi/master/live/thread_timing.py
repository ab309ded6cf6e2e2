"""The calling thread set up to keep deadlines (Linux; elsewhere nothing happens): its timer
slack, the process's memory locked, a real-time priority; each undone by its counterpart.
:class:`~deltafmi.master.live.pacing.Pacer` uses them from its start to its close."""
from __future__ import annotations

import ctypes
import ctypes.util
import os
import re
import sys
from pathlib import Path
from typing import Any, Callable, Optional, Tuple

__all__ = ["lock_memory", "real_time_priority", "restore_scheduling", "timer_slack", "unlock_memory"]

_PR_SET_TIMERSLACK, _PR_GET_TIMERSLACK = 29, 30
_MCL_CURRENT, _MCL_FUTURE, _MCL_ONFAULT = 1, 2, 4
_CAP_IPC_LOCK = 14


def _libc() -> Any:
    return ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)


def timer_slack(nanoseconds: Optional[int]) -> Optional[int]:
    """Set this thread's timer slack (Linux; elsewhere nothing happens) and return the one it
    had; None leaves it as it is."""
    try:
        libc = _libc()
        before = int(libc.prctl(_PR_GET_TIMERSLACK, 0, 0, 0, 0))
        if nanoseconds is not None:
            libc.prctl(_PR_SET_TIMERSLACK, nanoseconds, 0, 0, 0)
        return before if before > 0 else None
    except (OSError, AttributeError):
        return None


def lock_memory() -> bool:
    """Lock the process's pages in memory as they are faulted in (Linux ``mlockall``), where no
    later allocation can fail for it (locking without limit is permitted) and nothing is locked
    yet (a lock the program made stays its own); returns whether it locked."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        import resource

        status = Path("/proc/self/status").read_text()
        caps, locked = re.search(r"CapEff:\s*([0-9a-f]+)", status), re.search(r"VmLck:\s*(\d+)", status)
        unlimited = resource.getrlimit(resource.RLIMIT_MEMLOCK)[0] == resource.RLIM_INFINITY
        if caps is None or locked is None or int(locked.group(1)) or not (unlimited or int(caps.group(1), 16)
                                                                           >> _CAP_IPC_LOCK & 1):
            return False
        # MCL_ONFAULT: the pages mapped but never used are not read in (Python maps far more than it uses)
        return int(_libc().mlockall(_MCL_CURRENT | _MCL_FUTURE | _MCL_ONFAULT)) == 0
    except (OSError, AttributeError, ValueError, ImportError):
        return False


def real_time_priority(priority: int, warn: Callable[[str], None]) -> Optional[Tuple[int, int]]:
    """The calling thread at real-time ``priority`` (SCHED_FIFO); returns its scheduling before,
    or None (and a warning) where that is not permitted or not there."""
    if not hasattr(os, "sched_setscheduler"):
        warn(f"master.realtime.priority {priority}: real-time priorities are Linux's; paced at the usual priority")
        return None
    before = (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority)
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except OSError as exc:
        warn(f"master.realtime.priority {priority}: not permitted ({exc.strerror}: root, CAP_SYS_NICE or a "
             f"ulimit -r of at least {priority}); paced at the usual priority")
        return None
    return before


def unlock_memory() -> None:
    """Unlock the process's memory (after :func:`lock_memory` locked it)."""
    try:
        _libc().munlockall()
    except (OSError, AttributeError):
        pass


def restore_scheduling(scheduling: Tuple[int, int]) -> None:
    """The calling thread back to ``scheduling`` ((policy, priority), :func:`real_time_priority`'s)."""
    os.sched_setscheduler(0, scheduling[0], os.sched_param(scheduling[1]))
