"""A pooled FMU instance that repeats one of its earlier initializations from an FMU state snapshot.

Between ``instantiate`` (a reset, for a pooled instance) and ``fmi2ExitInitializationMode`` an FMU
sees a short, fixed sequence of calls from the master: the experiment's set-up, the start values,
initialization mode, the values copied in from other units and the values read out for them.
When a case gives a unit exactly the calls of an earlier case (the trajectory of a study that
varies the plant's mass; the plant of a grid whose other axis moves, each of its masses coming
back), initializing it again would bring it to the same state, so :class:`InitTranscript` keeps
the calls of an initialization, with what the reads returned, the messages it logged and an FMU
state taken right after it (``fmi2GetFMUstate``); an instance keeps the transcripts of its last
few distinct initializations. The next case is checked against them call by call while the FMU
is left alone (:class:`Replay`): each read gets its recorded values, and at
``fmi2ExitInitializationMode`` the FMU is set to the snapshot (``fmi2SetFMUstate``, which puts it
back in the state it was taken in, after ``fmi2Terminate`` too) and the recorded messages are
passed on. At the first call that differs from every kept transcript (another start value, other
copied inputs, another stop time) the instance is reset and the calls that matched are made for
real, and from there it initializes as it always did (and records the new transcript): a unit
whose parameters take a new value is always initialized afresh. Values are compared bit for bit
(``-0.0`` is not ``0.0``; a NaN matches the same NaN), ``1`` is not ``1.0``.

Only FMUs that declare ``canGetAndSetFMUstate`` take snapshots (FMI 2.0 and 3.0, Co-Simulation
and Model Exchange: a Model Exchange unit's snapshot is taken in Event Mode, where its event
iteration goes on; FMI 3.0 names the calls after its types and ``fmi3GetFMUState``); any call of
another FMI function before initialization ends makes the instance real first (an FMI 3.0 unit
whose Clocks' intervals the master asks for in initialization is always initialized).
"""
from __future__ import annotations

import io
import pickle
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

__all__ = ["InitTranscript", "Prefixes", "RECORDED_CALLS", "RECORDED_CALLS3", "Replay", "call_key"]

#: the fmpy methods recorded between instantiation and the end of initialization (FMI 2.0, FMI 3.0)
RECORDED_CALLS = ("setupExperiment", "setReal", "setInteger", "setBoolean", "setString", "getReal", "getInteger",
                  "getBoolean", "getString", "enterInitializationMode", "exitInitializationMode")
RECORDED_CALLS3 = tuple(f"{way}{kind}" for way in ("set", "get")
                        for kind in ("Float32", "Float64", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32",
                                     "Int64", "UInt64", "Boolean", "String", "Binary")) + (
    "enterInitializationMode", "exitInitializationMode")


def call_key(name: str, args: Tuple[Any, ...], kwargs: Dict[str, Any]) -> Any:
    """What two calls must share to be the same call: their pickle, which keeps a float's bits (the
    sign of zero, a NaN's payload) and every value's type (1 is not 1.0 nor True); a tuple
    argument counts as the list of its items. The values of String and Binary calls are pickled
    without pickle's memo (a string given twice is pickled twice, as two equal strings are); in
    other calls only a list given twice could be pickled the second time as a reference to the
    first, which makes the call match no other (never another call). A call whose arguments
    cannot be pickled matches no other."""
    if tuple in map(type, args):
        args = tuple(list(a) if type(a) is tuple else a for a in args)
    call = (name, args, sorted(kwargs.items()) if kwargs else ())
    try:
        if "String" not in name and "Binary" not in name:
            return pickle.dumps(call, 5)  # protocol fixed: the same call, the same bytes
        out = io.BytesIO()
        pickler = pickle.Pickler(out, 5)
        pickler.fast = True  # no memo
        pickler.dump(call)
        return out.getvalue()
    except Exception:  # noqa: BLE001 - an argument pickle cannot take: never the same call
        return object()


@dataclass(eq=False)
class Call:
    """One recorded call: its key, arguments (copies) and result."""

    key: Any
    name: str
    args: Tuple[Any, ...]
    kwargs: Dict[str, Any]
    result: Any = None


@dataclass(eq=False)  # by identity: an instance's list of kept ones finds and removes them (no call compared)
class InitTranscript:
    """The calls of one initialization, the messages the FMU logged meanwhile, and its state after."""

    calls: List[Call] = field(default_factory=list)
    messages: List[Tuple[Any, ...]] = field(default_factory=list)
    #: the FMU state right after fmi2ExitInitializationMode (None until taken)
    state: Any = None

    def record(self, name: str, args: Tuple[Any, ...], kwargs: Dict[str, Any],
               live: Callable[..., Any]) -> Any:
        """Make the call for real and keep it."""
        args = tuple(list(a) if isinstance(a, (list, tuple)) else a for a in args)
        result = live(*args, **kwargs)
        self.calls.append(Call(call_key(name, args, kwargs), name, args, dict(kwargs),
                               list(result) if isinstance(result, list) else result))
        return result


class Prefixes:
    """The kept transcripts of one instance as a tree of their calls: every call's key leads from
    the calls before it to the calls after it, so a case is matched against all the transcripts at
    once with one dictionary look-up per call, however many are kept. Transcripts that share their
    first calls share those nodes (they got the same values back there: an initialization is a
    function of its calls), with the calls of the most recently used one."""

    def __init__(self, transcripts: Sequence[InitTranscript]) -> None:
        #: call key -> (the recorded call, the node after it); a node after the last call of a
        #: transcript holds it under the key None
        self.root: Dict[Any, Any] = {}
        for transcript in transcripts:
            node = self.root
            for call in transcript.calls:
                known = node.get(call.key)
                if known is None:
                    known = node[call.key] = (call, {})
                node = known[1]
            node[None] = transcript


class Replay:
    """A case being checked against kept :class:`InitTranscript` s (their :class:`Prefixes`),
    one call at a time."""

    def __init__(self, prefixes: Prefixes) -> None:
        self._node = prefixes.root
        self._matched: List[Call] = []

    @property
    def transcript(self) -> InitTranscript:
        """The transcript whose calls all matched (after its last call)."""
        return self._node[None]

    def next(self, name: str, args: Tuple[Any, ...], kwargs: Dict[str, Any]) -> Optional[Call]:
        """The recorded call if this one is the same as the next recorded of some kept transcript
        (then advance), else None."""
        found = self._node.get(call_key(name, args, kwargs))
        if found is None:
            return None
        call, self._node = found
        self._matched.append(call)
        return call

    def matched(self) -> List[Call]:
        """The calls that matched so far."""
        return self._matched
