""":class:`EquationComponent`: an equation model that is an ordinary deltafmi component.

At class creation the model is flattened (:mod:`.model`, pure Python) and the module the
equation compiler generated from it is imported: inside an FMU from the FMU's own copy, at build
time from the build cache, where the builder writes it first (the compiler, and sympy, stay out
of the FMU). The module's INFO declares the states (``der()`` decided which variables they are);
its kernels become the component's compiled kernels (``native``) and its Python methods.
"""
from __future__ import annotations

import hashlib
import importlib
import importlib.util
import os
import sys
from pathlib import Path
from typing import Any, ClassVar, Optional

import numpy as np

from deltafmi.runtime import Component, Kernel, NativeKernels, State

from . import generated  # noqa: F401  (the package an FMU carries its generated module in)
from .model import EquationModelError, default_section, flatten

__all__ = ["COMPILER", "EquationComponent", "equations_cache", "generated_file"]

#: the package of the generated modules (an FMU carries its model's module in it)
GENERATED = "deltafmi.runtime.equations.generated"
#: set by the builder (deltafmi.builder.equations) when it is imported: (cls, flat, name) -> path
COMPILER: list = []


class EquationComponent(Component):
    """Base class of an equation model that becomes an FMU (see :mod:`deltafmi.runtime.equations`).

    ``constraint_pole``: the pole p of the stabilisation ``g'' + 2 p g' + p^2 g = 0`` of the
    constraints the index reduction differentiates (0: none; the projection holds them)."""

    constraint_pole: ClassVar[float] = 0.0
    #: a base class that other equation models extend (``partial = True``) is not compiled itself
    partial: ClassVar[bool] = False
    #: Model Exchange: a step event projects the states once a constraint residual exceeds this
    constraint_tolerance: ClassVar[float] = 1e-10
    _equations: ClassVar[Any] = None

    @default_section
    def equations(self) -> list:
        """The model's equations (see :class:`deltafmi.runtime.equations.Model`)."""
        return []

    @default_section
    def initial_equations(self) -> list:
        """Equations that hold at the start."""
        return []

    @default_section
    def algorithm(self) -> list:
        """Statements run in order at every event."""
        return []

    def __init_subclass__(cls, **kwargs: Any) -> None:
        if vars(cls).get("partial", False):  # Modelica's partial model: a base to extend, not compiled
            super().__init_subclass__(**kwargs)
            return
        flat = flatten(cls)
        module = _generated_module(cls, flat)
        cls._equations = module
        _declare(cls, module.INFO)
        super().__init_subclass__(**kwargs)

    # ------------------------------------------------------------------ the component's methods
    def setup(self) -> None:
        info = self._equations.INFO
        self._d = tuple(float(v[1]) for v in info["discrete"])
        self._pre_b = [False] * len(info["relations"])
        self._c_pre = [False] * info["n_whens"]

    def _args(self, t: float, x: Any = None) -> list:
        info = self._equations.INFO
        args: list = [t]
        if info["states"]:  # a model without states takes no state vector
            args.append(self.states.tolist() if x is None else x)
        args += [_value(getattr(self, _attribute(g))) for g in info["inputs"]]
        args += [_value(getattr(self, _attribute(g))) for g in info["parameters"]]
        if info["discrete"]:
            args.append(self._d)
        return args

    def derivatives(self, t: float) -> list:
        return list(self._equations.derivatives(*self._args(t)))

    def outputs(self, t: float) -> None:
        info = self._equations.INFO
        if info["outputs"]:
            self.write_reals(self._equations.outputs(*self._args(t)), *[_attribute(g) for g, _ in info["outputs"]])

    def event_indicators(self, t: float) -> list:
        if not self._equations.INFO["n_indicators"]:
            return []
        return list(self._equations.indicators(*self._args(t)))

    def initialize(self, t: float) -> None:
        self.setup()
        self._solve_initial(t)
        self._events(t, fire=False)

    def update(self, t: float) -> bool:
        self._events(t, fire=True)
        return False

    def _solve_initial(self, t: float) -> None:
        """Gauss-Newton (least squares, from the start values) on the initial equations and the
        invariants: states that neither fixes keep their start values as closely as they allow."""
        module = self._equations
        nx = len(module.INFO["states"])
        if not nx or (not module.N_INITIAL and not module.INFO["invariants"]):
            return
        x = np.array(self.states, dtype=float)
        for _ in range(50):
            r = np.array(module.initial_residual(*self._args(t, x.tolist())), dtype=float)
            if np.max(np.abs(r)) <= 1e-13 * max(1.0, np.max(np.abs(x))):
                break
            jac = np.array(module.initial_jacobian(*self._args(t, x.tolist())), dtype=float).reshape(len(r), nx)
            step = np.linalg.lstsq(jac, -r, rcond=None)[0]
            x = x + step
            if np.max(np.abs(step)) <= 1e-15 * max(1.0, np.max(np.abs(x))):
                break
        r = np.array(module.initial_residual(*self._args(t, x.tolist())), dtype=float)
        if not np.all(np.isfinite(r)) or np.max(np.abs(r)) > 1e-9 * max(1.0, np.max(np.abs(x))):
            raise EquationModelError(f"{type(self).__name__}: the initial equations have no solution near the start "
                                     f"values (residual {np.max(np.abs(r)):.3g})")
        self.states[:] = x

    def _events(self, t: float, fire: bool) -> None:
        module = self._equations
        info = module.INFO
        if not hasattr(module, "event_pass"):
            return
        pre_x = self.states.tolist()
        for _ in range(20):
            z = self.event_indicators(t) if info["n_indicators"] else []
            b = [(z[i] > 0.0) if kind == "gt" else (z[i] <= 0.0) for i, kind in info["relations"]]
            args = self._args(t)
            states = args[1] if info["states"] else []  # a model without states takes none
            x, d, c = module.event_pass(*args, pre_x, list(self._d), b, self._pre_b, self._c_pre, fire)
            changed = tuple(d) != self._d or x != states
            self._pre_b, self._c_pre = b, c
            self._d = tuple(float(v) for v in d)
            if x != states:
                self.states[:] = x
            if not changed:
                break
        for (name, _, group), value in zip(info["discrete"], self._d):
            declaration = getattr(type(self), _attribute(group), None)
            if declaration is not None:
                setattr(self, _attribute(group), declaration.type(value))


def _jacobian(self: EquationComponent, t: float) -> dict:
    """Exact partial derivatives of the state derivatives and outputs by the states and Real
    inputs: the implicit function theorem on the sorted system, dz/dk = -F_z^-1 F_k."""
    info = self._equations.INFO["jacobian"]
    nz, nk = info["nz"], info["nk"]
    parts = np.array(self._equations.jacobian_parts(*self._args(t)), dtype=float)
    fz, fk = parts[:nz * nz].reshape(nz, nz), parts[nz * nz:].reshape(nz, nk)
    # an equation not differentiable here (|h| at h = 0): what it determines is left to the
    # runtime's differences, and so is everything that depends on it
    bad = [r for r in range(nz) if not (np.all(np.isfinite(fz[r])) and np.all(np.isfinite(fk[r])))]
    unknown = set()
    for r in bad:
        fz[r], fk[r] = 0.0, 0.0
        fz[r, info["matched"][r]] = 1.0
        unknown.add(info["matched"][r])
    dz = -np.linalg.solve(fz, fk)
    if unknown:  # and what depends on them, through the equations that determine it
        row_of = {m: r for r, m in enumerate(info["matched"])}
        changed = True
        while changed:
            changed = False
            for j in range(nz):
                if j not in unknown and any(fz[row_of[j], i] != 0.0 for i in unknown):
                    unknown.add(j)
                    changed = True
    eye = np.eye(nk)

    def rows(where: list) -> Optional[np.ndarray]:
        if any(kind == "z" and i in unknown for kind, i in where):
            return None
        return np.array([dz[i] if kind == "z" else eye[i] for kind, i in where])

    out = {"der": rows(info["der"])}
    out.update({_attribute(g): rows(where) for g, where in info["outputs"].items()})
    return {key: value for key, value in out.items() if value is not None}


def _project(self: EquationComponent, t: float) -> None:
    self.states[:] = self._equations.project(*self._args(t))


def _needs_projection(self: EquationComponent, t: float) -> bool:
    residual = self._equations.invariants(*self._args(t))
    return max(abs(v) for v in residual) > self.constraint_tolerance


def _value(v: Any) -> Any:
    return v.tolist() if isinstance(v, np.ndarray) else v


def _attribute(group: str) -> str:
    return "".join(ch if ch.isalnum() else "_" for ch in group)


def _declare(cls: type, info: dict) -> None:
    """State declarations for the states the compiler found, the kernels, the event indicators."""
    groups: dict = {}
    for name, group, index, start, unit in info["states"]:
        groups.setdefault(group, []).append((start, unit))
    for group, members in groups.items():
        attribute = _attribute(group)
        existing = vars(cls).get(attribute)
        if isinstance(existing, State):
            continue
        starts = [s for s, _ in members]
        decl = State(starts if len(members) > 1 or group.endswith("]") is False and len(members) > 1 else starts[0],
                     unit=members[0][1], name=group, description=f"state {group} (chosen by der())")
        if len(members) > 1:
            decl = State(starts, unit=members[0][1], name=group, description=f"state {group} (chosen by der())")
        setattr(cls, attribute, decl)
        decl.__set_name__(cls, attribute)
        decl.fmi_name = group
    cls.n_event_indicators = info["n_indicators"]
    module = cls._equations
    args = ["t"] + (["states"] if info["states"] else []) + [_attribute(g) for g in info["inputs"]] \
        + [_attribute(g) for g in info["parameters"]]
    attributes = {}
    if info["discrete"]:
        args.append("_d")
        attributes["_d"] = tuple.__class_getitem__((float,) * len(info["discrete"]))
    kernels = dict(derivatives=Kernel(module.derivatives, *args)) if info["states"] else {}
    if info["outputs"]:
        kernels["outputs"] = Kernel(module.outputs, *args, returns=tuple(_attribute(g) for g, _ in info["outputs"]))
    if info["n_indicators"]:
        kernels["event_indicators"] = Kernel(module.indicators, *args)
    if info.get("jacobian"):
        cls.jacobian = _jacobian
    if info["invariants"]:
        kernels["project"] = Kernel(module.project, *args)
        cls.project = _project
        cls.needs_projection = _needs_projection
    cls.native = NativeKernels(**kernels, attributes=attributes)


def equations_cache(name: str) -> Optional[Path]:
    """Where the build cache keeps generated module ``name``: a folder per version of the
    compiler's sources (read, not imported); None where there is no compiler (inside an FMU)."""
    compiler = Path(__file__).resolve().parents[2] / "builder" / "equations"
    sources = sorted(compiler.glob("*.py"))
    if not sources:
        return None
    digest = hashlib.sha256(b"".join(p.read_bytes() for p in sources)).hexdigest()[:16]
    root = Path(os.environ.get("DELTAFMI_CACHE", Path.home() / ".cache" / "deltafmi"))
    return root / "equations" / digest / f"{name}.py"


def _generated_module(cls: type, flat: Any) -> Any:
    """The module generated from ``flat``: the FMU's copy, else the build cache's (compiled now
    when missing; only then is the compiler imported)."""
    name = f"m_{cls.__name__}_{flat.key()[:16]}_p{str(getattr(cls, 'constraint_pole', 0.0)).replace('.', '_')}"
    full = f"{GENERATED}.{name}"
    local = f"_deltafmi_equations_{name}"  # outside deltafmi: the FMU carries it as ``full``
    for module_name in (full, local):
        if module_name in sys.modules:
            return sys.modules[module_name]
    try:
        return importlib.import_module(full)
    except ModuleNotFoundError:
        pass
    path = equations_cache(name)
    if path is None or not path.is_file():
        if not COMPILER:  # the builder registers its compiler when imported; the runtime never imports it
            raise EquationModelError(f"{cls.__name__}: its equations are not compiled yet; build it "
                                     f"(deltafmi build, deltafmi.build_fmu) or import deltafmi.builder first")
        path = COMPILER[0](cls, flat, name)
    spec = importlib.util.spec_from_file_location(local, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[local] = module
    spec.loader.exec_module(module)
    module.__deltafmi_generated_file__ = str(path)
    module.__deltafmi_fmu_module__ = full
    return module


def generated_file(cls: type) -> Optional[tuple]:
    """(path, module name) of the generated module of an equation component, for the packager."""
    module = getattr(cls, "_equations", None)
    path = getattr(module, "__deltafmi_generated_file__", None) or getattr(module, "__file__", None)
    return (path, getattr(module, "__deltafmi_fmu_module__", module.__name__)) if path else None
