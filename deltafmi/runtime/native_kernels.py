"""The run-time side of a component's compiled kernels (see :mod:`.native`).

``deltafmi build`` puts the generated C library in the FMU's binaries folder and describes it in
``resources/native_kernels.json``: the library's path in the FMU, the kernels it has, and the C
layout of the component attributes they read. :class:`NativeKernelsRuntime` loads the library,
keeps one C struct of those attributes per instance and copies the component's attributes into it
(:meth:`NativeKernelsRuntime.pack`) whenever the model may have changed them; the FMU's C layer
then calls the kernels directly, with no Python, while ``ready`` is set.

A layout description is JSON: ``"double"``, ``"int"``, ``"bool"`` (an int in C), ``"str"``;
``{"object": [field, ...]}`` (a dataclass of floats); ``{"record": [[field, description], ...]}``
(a NamedTuple or an object's attributes); ``{"tuple": [description, ...]}`` (fields f0, f1, ...);
``{"array": description, "n": n}`` (a struct of one array ``v``); ``{"optional": description}``
(``some`` flag and value ``v``). Set ``DELTAFMI_NATIVE=0`` in the environment to run the Python
methods instead (for comparisons), ``DELTAFMI_NATIVE_PROJECT=0`` to keep only CVODE's projection in
Python (``project``; the other kernels compiled: its cost alone).
"""
from __future__ import annotations

import ctypes
import json
import os
import struct
from pathlib import Path
from typing import Any, Callable, Optional

import numpy as np

__all__ = ["DESCRIPTION", "FieldWriter", "NativeKernelsRuntime", "c_type", "field_name", "pack", "record_classes",
           "unpack"]

#: the description file in an FMU's resources folder
DESCRIPTION = "native_kernels.json"
#: the kernels' roles, in the order the loader's layout takes their addresses
ROLES = ("derivatives", "event_indicators", "outputs", "step", "update")
#: the roles only CVODE calls (through :meth:`NativeKernelsRuntime.cvode_callbacks`), not the loader
CVODE_ROLES = ("project", "state_jacobian")
#: the roles the Python side calls itself (:meth:`NativeKernelsRuntime.jacobian_values`)
PYTHON_ROLES = ("jacobian",)
#: kernels whose addresses trail the layout (after the attributes' struct and the ready flag)
TRAILING_ROLES = ("drift",)
_SCALARS = {"double": ctypes.c_double, "int": ctypes.c_int, "bool": ctypes.c_int, "str": ctypes.c_char_p}
_TYPES: dict[str, Any] = {}


def c_type(desc: Any) -> Any:
    """The ctypes type laid out as the C type the description names."""
    if isinstance(desc, str):
        return _SCALARS[desc]
    key = json.dumps(desc, sort_keys=True)
    if key not in _TYPES:
        if "object" in desc:
            fields = [(name, ctypes.c_double) for name in desc["object"]]
        elif "record" in desc:
            fields = [(name, c_type(item)) for name, item in desc["record"]]
        elif "tuple" in desc:
            fields = [(f"f{k}", c_type(item)) for k, item in enumerate(desc["tuple"])]
        elif "array" in desc:
            fields = [("v", c_type(desc["array"]) * desc["n"])]
        else:
            fields = [("some", ctypes.c_int), ("v", c_type(desc["optional"]))]
        _TYPES[key] = type("KernelStruct", (ctypes.Structure,), {"_fields_": fields})
    return _TYPES[key]


def pack(desc: Any, value: Any) -> Any:
    """``value`` as a ctypes value of the described type, built field by field (the reference the
    runtime's :class:`FieldWriter` is tested against, and codegen/build.py's marshalling);
    TypeError/ValueError when it does not fit."""
    if isinstance(desc, str):
        if desc == "double":
            return float(value)
        if desc == "str":
            return value.encode()
        number = int(value)
        if not -2 ** 31 <= number < 2 ** 31:
            raise OverflowError(f"{number} does not fit a C int")
        return number
    out = c_type(desc)()
    if "object" in desc:
        for name in desc["object"]:
            setattr(out, name, float(getattr(value, name)))
    elif "record" in desc:
        for name, item in desc["record"]:
            setattr(out, name, pack(item, getattr(value, name)))
    elif "tuple" in desc:
        if len(value) != len(desc["tuple"]):
            raise ValueError(f"{len(value)} items where the kernel takes {len(desc['tuple'])}")
        for k, item in enumerate(desc["tuple"]):
            setattr(out, f"f{k}", pack(item, value[k]))
    elif "array" in desc:
        if len(value) != desc["n"]:
            raise ValueError(f"{len(value)} items where the kernel takes {desc['n']}")
        for k in range(desc["n"]):
            out.v[k] = pack(desc["array"], value[k])
    else:
        out.some = value is not None
        if value is not None:
            out.v = pack(desc["optional"], value)
    return out


def _has_records(desc: Any) -> bool:
    if isinstance(desc, str) or "object" in desc:
        return False
    if "record" in desc:
        return True
    known = _HAS_RECORDS.get(id(desc))
    if known is not None and known[0] is desc:
        return known[1]
    items = desc.get("tuple") or [desc.get("array") or desc.get("optional")]
    found = any(_has_records(item) for item in items)
    if len(_HAS_RECORDS) > 4096:  # descriptions of kernels loaded long ago: asked again if need be
        _HAS_RECORDS.clear()
    _HAS_RECORDS[id(desc)] = (desc, found)
    return found


#: :func:`_has_records` of the tuple, array and optional descriptions seen (by identity, each kept
#: with its answer): a pack at every restore asks again at every level of a value
_HAS_RECORDS: dict = {}


def record_classes(desc: Any, value: Any, classes: dict, path: str = "") -> None:
    """The class of every record in ``value`` by its path, into ``classes`` (what :func:`unpack`
    builds them back with)."""
    if value is None or not _has_records(desc):
        return
    if "record" in desc:
        classes[path] = type(value)
        for name, item in desc["record"]:
            record_classes(item, getattr(value, name), classes, f"{path}.{name}")
    elif "tuple" in desc:
        for k, item in enumerate(desc["tuple"]):
            record_classes(item, value[k], classes, f"{path}[{k}]")
    elif "array" in desc:
        for item in value:
            record_classes(desc["array"], item, classes, f"{path}[]")
    else:
        record_classes(desc["optional"], value, classes, f"{path}?")


class FieldWriter:
    """Writes a value of one layout description into a struct at a given offset with a single
    ``struct.pack_into``: a format with the C layout's offsets and padding, and a function made
    once that lists the value's scalars in that order. (Building ctypes structs field by field
    took up to 0.25 ms for the trajectory's table, at every initialization and event.)"""

    def __init__(self, desc: Any, offset: int) -> None:
        leaves: list[tuple[int, str]] = []
        items = self._items(desc, c_type(desc), 0, "v", leaves)
        fmt, position = "<", 0
        for at, code in leaves:
            fmt += f"{at - position}x{code}" if at > position else code
            position = at + struct.calcsize("<" + code)
        self.format = struct.Struct(fmt)
        self.offset = offset
        self._strings: list = []
        self.flatten = eval(f"lambda v, cstr: ({', '.join(items)},)", {})  # noqa: S307 (our own expressions)

    def write(self, target: Any, value: Any) -> None:
        """``value`` into ``target`` (a ctypes struct) at the offset; TypeError, ValueError or
        struct.error when it does not fit the description."""
        strings: list = []

        def cstr(text: str) -> int:
            strings.append(ctypes.c_char_p(text.encode()))
            return ctypes.cast(strings[-1], ctypes.c_void_p).value or 0

        self.format.pack_into(target, self.offset, *self.flatten(value, cstr))
        self._strings = strings  # the C struct points into them: kept until the next write

    def _items(self, desc: Any, ctype: Any, base: int, expr: str, leaves: list) -> list[str]:
        """The Python expressions of the scalars of ``expr`` (starred where an Optional expands),
        their (offset, struct code) appended to ``leaves``."""
        if isinstance(desc, str):
            leaves.append((base, {"double": "d", "int": "i", "bool": "i", "str": "Q"}[desc]))
            return [f"cstr({expr})" if desc == "str" else expr]
        if "object" in desc:
            return [item for name in desc["object"]
                    for item in self._items("double", None, base + getattr(ctype, name).offset, f"{expr}.{name}", leaves)]
        if "record" in desc or "tuple" in desc:
            named = desc.get("record") or [(f"f{k}", item) for k, item in enumerate(desc["tuple"])]
            types = dict(ctype._fields_)
            return [item for k, (name, sub) in enumerate(named)
                    for item in self._items(sub, types[name], base + getattr(ctype, name).offset,
                                            f"{expr}.{name}" if "record" in desc else f"{expr}[{k}]", leaves)]
        if "array" in desc:
            element = dict(ctype._fields_)["v"]._type_
            start = base + ctype.v.offset
            return [item for k in range(desc["n"])
                    for item in self._items(desc["array"], element, start + k * ctypes.sizeof(element), f"{expr}[{k}]",
                                            leaves)]
        inner_type = dict(ctype._fields_)["v"]
        leaves.append((base + ctype.some.offset, "i"))
        before = len(leaves)
        inner = self._items(desc["optional"], inner_type, base + ctype.v.offset, "o", leaves)
        zeros = ["0.0" if code == "d" else "0" for _, code in leaves[before:]]
        return [f"*((1, *(lambda o: ({', '.join(inner)},))({expr})) if {expr} is not None else (0, {', '.join(zeros)}))"]


def unpack(desc: Any, value: Any, classes: dict, path: str = "") -> Any:
    """The Python value of a ctypes value of the described type (the inverse of :func:`pack`:
    records become the classes :func:`pack` saw, sequences tuples)."""
    if isinstance(desc, str):
        return {"double": float, "bool": bool, "int": int, "str": bytes.decode}[desc](value)
    if "record" in desc:
        return classes[path](*[unpack(item, getattr(value, name), classes, f"{path}.{name}")
                               for name, item in desc["record"]])
    if "tuple" in desc:
        return tuple(unpack(item, getattr(value, f"f{k}"), classes, f"{path}[{k}]")
                     for k, item in enumerate(desc["tuple"]))
    if "array" in desc:
        return tuple(unpack(desc["array"], item, classes, f"{path}[]") for item in value.v)
    if "optional" in desc:
        return unpack(desc["optional"], value.v, classes, f"{path}?") if value.some else None
    raise TypeError(f"a kernel does not update {desc}")


_SCALAR_TYPES = frozenset((float, int, bool, str, type(None)))


def _immutable(value: Any) -> bool:
    """Whether ``value`` cannot change in place (a tuple of such, a frozen dataclass, a number)."""
    if isinstance(value, tuple):
        # the scalars of a long tuple (a path's samples) checked without a call each
        return all(type(item) in _SCALAR_TYPES or _immutable(item) for item in value)
    params = getattr(type(value), "__dataclass_params__", None)
    return params.frozen if params is not None else isinstance(value, (int, float, str, type(None)))


def field_name(attribute: str) -> str:
    """The C field of an attribute (a dotted path ``_ctl.state`` -> ``_ctl_state``)."""
    return attribute.replace(".", "_")


def _get(obj: Any, path: str) -> Any:
    for name in path.split("."):
        obj = getattr(obj, name)
    return obj


def _set(obj: Any, path: str, value: Any) -> None:
    owner, _, name = path.rpartition(".")
    setattr(_get(obj, owner) if owner else obj, name, value)


class _CvodeData(ctypes.Structure):
    """The user data of dfmi_kernel_cvode_rhs/_roots/_project (deltafmi/builder/codegen/cvode_rhs.c)."""

    _fields_ = [("attributes", ctypes.c_void_p), ("ready", ctypes.c_void_p), ("real", ctypes.c_void_p),
                ("ints", ctypes.c_void_p), ("nx", ctypes.c_long), ("x_offset", ctypes.c_long),
                ("dx_offset", ctypes.c_long), ("nz", ctypes.c_long), ("array", ctypes.c_void_p),
                ("fallback", ctypes.c_void_p), ("roots_fallback", ctypes.c_void_p),
                ("project_fallback", ctypes.c_void_p), ("jacobian_fallback", ctypes.c_void_p),
                ("matrix", ctypes.c_void_p)]


class NativeKernelsRuntime:
    """One instance's compiled kernels: their addresses and its attributes' C struct."""

    def __init__(self, library: Path, description: dict) -> None:
        self.library = ctypes.CDLL(str(library))
        self.attributes = description["attributes"]  # [[name, layout description], ...]
        #: the functions the component calls itself (see native_functions.py), by name
        self.function_descriptions = description.get("functions", {})
        self.updates = [(name, desc) for name, desc in self.attributes if name in description.get("updates", ())]
        fields = [("changed", ctypes.c_int)] + [(field_name(name), c_type(desc)) for name, desc in self.attributes]
        struct_type = type("Attributes", (ctypes.Structure,), {"_fields_": fields})
        self.struct = struct_type()
        self._writers = {name: FieldWriter(desc, getattr(struct_type, field_name(name)).offset)
                         for name, desc in self.attributes}
        self._written: dict[str, Any] = {}  # the immutable values in the struct now, by attribute
        self._classes: dict[str, type] = {}
        size = ctypes.c_size_t.in_dll(self.library, "dfmi_kernel_attributes_size").value
        if size != ctypes.sizeof(self.struct):
            raise ImportError(f"{library}: its attributes take {size} bytes, the description "
                              f"{ctypes.sizeof(self.struct)}: rebuild the FMU")
        functions = [getattr(self.library, f"dfmi_kernel_{role}") if role in description["kernels"] else None
                     for role in ROLES]
        for role, function in zip(ROLES, functions):
            if function is not None:
                # (attributes, time[, h], real, ints[, indicators or next_event_time])
                times = [ctypes.c_double] * (2 if role == "step" else 1)
                function.argtypes = [ctypes.c_void_p, *times] + [ctypes.c_void_p] * (2 if role == "step" else 3)
                function.restype = ctypes.c_int
        self._functions = functions
        self.addresses = [ctypes.cast(f, ctypes.c_void_p).value if f is not None else 0 for f in functions]
        self.trailing = [ctypes.cast(getattr(self.library, f"dfmi_kernel_{role}"), ctypes.c_void_p).value
                         if role in description["kernels"] else 0 for role in TRAILING_ROLES]
        self._cvode_roles = {role for role in CVODE_ROLES if role in description["kernels"]}
        self._jacobian = None
        if "jacobian" in description["kernels"]:
            self._jacobian = self.library.dfmi_kernel_jacobian
            self._jacobian.argtypes = [ctypes.c_void_p, ctypes.c_double] + [ctypes.c_void_p] * 3
            self._jacobian.restype = ctypes.c_int
            self._jacobian_values = np.zeros(description["jacobian_size"])
        self._buffers = (None, None, None)
        #: [0] nonzero while the struct holds the component's current attributes
        self.ready = np.zeros(1, dtype=np.intc)
        self._cvode_data: list = []

    @classmethod
    def load(cls, resources_dir: str) -> Optional[NativeKernelsRuntime]:
        """The kernels the FMU whose resources are at ``resources_dir`` carries (None: none, or
        ``DELTAFMI_NATIVE=0``)."""
        path = Path(resources_dir or ".") / DESCRIPTION
        if os.environ.get("DELTAFMI_NATIVE", "1") == "0" or not path.is_file():
            return None
        description = json.loads(path.read_text())
        return cls(path.parent.parent / description["library"], description)

    def attach(self, real: np.ndarray, ints: np.ndarray, indicators: np.ndarray) -> None:
        """The instance's value buffers and event indicators (the same for its whole life,
        fmi2Reset included)."""
        self._buffers = (real.ctypes.data, ints.ctypes.data, indicators.ctypes.data)

    def evaluate(self, t: float, nx: int, nz: int) -> bool:
        """Derivatives and outputs at ``t`` by the kernels, as the FMU's C layer computes them
        (for the runtime's own evaluations, at the end of a Co-Simulation step); False, with
        nothing computed, when the kernels are off, do not cover all of it (event indicators,
        a missing kernel) or raised."""
        derivatives, indicators, outputs, _, _ = self._functions
        if not self.ready[0] or (nx and derivatives is None) or (nz and indicators is None) or outputs is None:
            return False
        address = ctypes.addressof(self.struct)
        return ((not nx or derivatives(address, t, *self._buffers) == 0)
                and (not nz or indicators(address, t, *self._buffers) == 0)
                and outputs(address, t, *self._buffers) == 0)

    def derivatives(self, t: float) -> bool:
        """The state derivatives at ``t`` into the value buffer by the kernel; False (nothing
        written) when the kernels are off, there is none, or it raised."""
        kernel = self._functions[0]
        return bool(self.ready[0]) and kernel is not None and kernel(ctypes.addressof(self.struct), t,
                                                                      *self._buffers) == 0

    def outputs(self, t: float) -> bool:
        """The outputs at ``t`` into the value buffer by the kernel; False (nothing written) when
        the kernels are off, there is none, or it raised."""
        kernel = self._functions[2]
        return bool(self.ready[0]) and kernel is not None and kernel(ctypes.addressof(self.struct), t,
                                                                      *self._buffers) == 0

    def jacobian_values(self, t: float) -> Optional[np.ndarray]:
        """The jacobian kernel's floats at ``t`` (a new array), or None when the kernels are off,
        there is none, or it raised."""
        if self._jacobian is None or not self.ready[0]:
            return None
        real, ints, _ = self._buffers
        values = self._jacobian_values
        if self._jacobian(ctypes.addressof(self.struct), t, real, ints, values.ctypes.data) != 0:
            return None
        return values.copy()

    def has(self, role: str) -> bool:
        """Whether the library has the kernel of ``role``."""
        if role in CVODE_ROLES:
            return role in self._cvode_roles
        if role in PYTHON_ROLES:
            return self._jacobian is not None
        if role in TRAILING_ROLES:
            return bool(self.trailing[TRAILING_ROLES.index(role)])
        return bool(self.addresses[ROLES.index(role)])

    def cvode_callbacks(self, x_offset: int, dx_offset: int, nx: int,
                        nz: int) -> Callable[..., tuple[int, int, int, int, int]]:
        """The compiled derivatives (event indicators, projection, state Jacobian) as CVODE's
        right-hand side (root functions, projection function, Jacobian function) over the value
        buffers (``Cvode``'s ``native``): they call the Python ones while the kernels are off or
        when they raise. The projection stays Python without a project kernel or with
        ``DELTAFMI_NATIVE_PROJECT=0``; the Jacobian without a state_jacobian kernel or a Python one."""
        project_native = self.has("project") and os.environ.get("DELTAFMI_NATIVE_PROJECT", "1") != "0"

        def bind(rhs: int, roots: int, project: int, array: int, jacobian: int = 0,
                 matrix: int = 0) -> tuple[int, int, int, int, int]:
            real, ints, _ = self._buffers
            data = _CvodeData(ctypes.addressof(self.struct), self.ready.ctypes.data, real, ints, nx, x_offset,
                              dx_offset, nz, array, rhs, roots, project, jacobian, matrix)
            # CVODE holds its address; an instance has one solver at a time (a new one only after
            # the old is freed), so only the newest is kept: appending grew ~230 B per fmi2Reset
            self._cvode_data[:] = [data]
            roots_address = (self._address("dfmi_kernel_cvode_roots")
                             if nz and self.has("event_indicators") else 0)
            project_address = self._address("dfmi_kernel_cvode_project") if project and project_native else 0
            jacobian_address = (self._address("dfmi_kernel_cvode_jacobian")
                                if jacobian and matrix and self.has("state_jacobian") else 0)
            return (self._address("dfmi_kernel_cvode_rhs"), roots_address, project_address, jacobian_address,
                    ctypes.addressof(data))

        return bind

    def _address(self, name: str) -> int:
        return ctypes.cast(getattr(self.library, name), ctypes.c_void_p).value or 0

    def pack(self, component: Any) -> None:
        """Copy the component's attributes into the C struct; an attribute that does not fit
        (None, another type) leaves the kernels off until the next pack."""
        if self.struct.changed:  # what compiled steps wrote (their updates) and nobody read: overwritten
            for name, _ in self.updates:
                self._written.pop(name, None)
        self.ready[0] = self.struct.changed = 0  # the component's attributes are the truth now
        try:
            for name, desc in self.attributes:
                value = _get(component, name)
                if value is not self._written.get(name):  # NamedTuples and frozen dataclasses: once each
                    self._writers[name].write(self.struct, value)
                    self._written[name] = value if _immutable(value) else None
                    record_classes(desc, value, self._classes, name)
        except (AttributeError, TypeError, ValueError, ArithmeticError, struct.error):
            self._written.clear()
            return
        self.ready[0] = 1

    def pull(self, component: Any) -> None:
        """The attributes a compiled step changed, back into the component (before Python reads them)."""
        if self.struct.changed:
            for name, desc in self.updates:
                value = unpack(desc, getattr(self.struct, field_name(name)), self._classes, name)
                _set(component, name, value)
                self._written[name] = value if _immutable(value) else None
            self.struct.changed = 0

    def layout(self) -> tuple:
        """The trailing fields of FmuInstance.native_layout: the kernels' addresses (0: none), the
        attributes' address and the ready flag's, then the drift kernel's address (0: none)."""
        return (*self.addresses, ctypes.addressof(self.struct), self.ready.ctypes.data, *self.trailing)
