"""A component's declared kernels (``native = NativeKernels(...)``) as one C library for its FMU.

:func:`generate_component` translates the kernels and writes the glue the FMU's loader calls:
one function per role with the fixed signature ``int dfmi_kernel_<role>(const void *attributes,
double time, double *real, int *ints, double *indicators)`` (a step: ``(void *attributes, double
time, double h, double *real, int *ints)``, an update: ``(void *attributes, double time, double
*real, int *ints, double *next_event_time)``) that reads the kernel's arguments from the value buffers
(at the layout's offsets, constants in the C) and from the attributes' struct, calls the kernel
and writes its result into the buffers (a projection: the states) only when it succeeded (0;
else the line of the ``raise`` it took: the loader then calls the Python method, which raises
with its message). CVODE's projection (``project``) is called by CVODE alone (cvode_rhs.c).
The functions a component calls itself (``NativeKernels(functions=...)``) get one exported entry
each, ``int dfmi_function_<name>(<arguments>, double *values)`` (see
deltafmi/runtime/native_functions.py). :func:`component_library` compiles it (cached) for
``deltafmi build``; :func:`use_compiled_functions` loads it for the component's instances in this
process.
"""
from __future__ import annotations

import copy
import dataclasses
import hashlib
import warnings
import weakref
from pathlib import Path
from typing import Any, NamedTuple, Optional

from deltafmi.runtime import Component
from deltafmi.runtime.native import Kernel
from deltafmi.runtime.native_functions import register_library
from deltafmi.runtime.native_kernels import field_name
from deltafmi.runtime.variables import State
from deltafmi.toolchain import BuildError, NoCompilerError, build_into, cache_dir, single_file_library
from .build import CFLAGS
from .kernel_types import NONE, B, CodegenError, D, Entry, I, Obj, Opt, S, Tup, Vec, _type_of_hint, describe
from .translate import generate

__all__ = ["component_library", "generate_component", "use_compiled_functions"]

#: helpers taken as the identity: list conversions that fixed-length C arrays make unnecessary
IDENTITIES = ("_as_list", "_f3")
EXPORT = '__attribute__((visibility("default")))'
#: the oldest versions of the glibc functions kernels call whose default version is recent (libm's
#: exp, log, pow got new ones in glibc 2.29, memcpy in 2.14: the same functions, only their error
#: reporting through errno differs), so that the library loads where the FMU binary does
#: (deltafmi/runtime/native/glibc_floor.h) and a wheel's prebuilt ones pass as manylinux
GLIBC_FLOOR = "\n".join(["/* glibc: the oldest versions of what the kernels call (deltafmi.builder.codegen) */",
                         "#if defined(__x86_64__) && defined(__linux__)",
                         *[f'__asm__(".symver {name},{name}@GLIBC_2.2.5");'
                           for name in ("memcpy", "pow", "exp", "log", "exp2", "log2")],
                         "#endif"])
#: CVODE's right-hand side, root and projection functions over the kernels (Co-Simulation)
CVODE_RHS = Path(__file__).with_name("cvode_rhs.c")


class GeneratedKernels(NamedTuple):
    """The C translation unit of a component's kernels and the run-time description
    (deltafmi/runtime/native_kernels.py) of what it needs."""

    source: str
    description: dict


class ComponentLibrary(NamedTuple):
    """A component's compiled kernels: the library, its C source and its description."""

    library: Path
    source: Path
    description: dict


def generate_component(cls: type[Component]) -> Optional[GeneratedKernels]:
    """The C of ``cls.native`` (None when it declares none or ``mode="off"``).

    Raises :class:`CodegenError` naming the file and line of what cannot be translated, or the
    component and argument that is neither a variable nor a declared attribute."""
    native = getattr(cls, "native", None)
    if native is None or native.mode == "off" or not (native.kernels() or native.functions):
        return None
    _check_inherited(cls)
    _check_step(cls)
    if native.project is not None and native.derivatives is None:
        raise CodegenError(f"{cls.__name__}.native: a project kernel is CVODE's projection, which runs with the "
                           f"compiled right-hand side: declare the derivatives kernel too")
    if native.state_jacobian is not None and native.derivatives is None:
        raise CodegenError(f"{cls.__name__}.native: a state_jacobian kernel is CVODE's Newton matrix, which runs "
                           f"with the compiled right-hand side: declare the derivatives kernel too")
    attributes = {name: _attribute_type(cls, name, spec) for name, spec in native.attributes.items()}
    entries, glue = [], []
    for role, kernel in native.kernels().items():
        args = [_argument(cls, role, name, attributes) for name in kernel.args]
        entries.append(Entry(f"dfk_{role}", kernel.func, [t for t, _ in args]))
        glue.append((role, kernel, args))
    functions = {name: [_function_argument(cls, name, k, spec) for k, spec in enumerate(function.args)]
                 for name, function in native.functions.items()}
    entries += [Entry(f"dfn_{name}", native.functions[name].func, types) for name, types in functions.items()]
    returns: dict = {}
    type_names: dict = {t: "" for t in attributes.values()}
    unit = generate(entries, identities=IDENTITIES, returns=returns, type_names=type_names)
    fields = " ".join(f"{type_names[t]} {field_name(name)};" for name, t in attributes.items())
    parts = [GLIBC_FLOOR, unit,
             f"/* ---- glue: {cls.__name__}'s buffers and attributes -> kernels "
             f"(deltafmi.builder.codegen.component_kernels) ---- */",
             "/* changed: set by a step that updated attributes (Python copies them back, then clears it) */",
             f"typedef struct {{ int changed; {fields} }} DfmiAttributes;",
             f"{EXPORT} const size_t dfmi_kernel_attributes_size = sizeof(DfmiAttributes);"]
    for role, kernel, args in glue:
        parts.append(_glue(cls, role, kernel, args, returns[f"dfk_{role}"], attributes))
    described = {}
    for name, types in functions.items():
        code, described[name] = _function_glue(cls, name, native.functions[name].func, types, returns[f"dfn_{name}"])
        parts.append(code)
    if native.derivatives is not None:
        indicators, project = int(native.event_indicators is not None), int(native.project is not None)
        state_jacobian = int(native.state_jacobian is not None)
        parts.append(f"#define EXPORT {EXPORT}\n#define DFMI_KERNEL_INDICATORS {indicators}\n"
                     f"#define DFMI_KERNEL_PROJECT {project}\n#define DFMI_KERNEL_STATE_JACOBIAN {state_jacobian}\n"
                     f"{CVODE_RHS.read_text()}")
    description = {"kernels": list(native.kernels()),
                   "attributes": [[name, describe(t)] for name, t in attributes.items()],
                   "updates": list(native.step.updates) if native.step is not None else []}
    if described:
        description["functions"] = described
    if native.jacobian is not None:
        description["jacobian_size"] = len(_leaves(returns["dfk_jacobian"], "out", f"{cls.__name__}.native.jacobian"))
    return GeneratedKernels("\n".join(parts) + "\n", description)


#: the method each role's kernel stands for
_METHODS = {"derivatives": "derivatives", "event_indicators": "event_indicators", "outputs": "outputs",
            "step": "do_step", "update": "update", "project": "project",
            "jacobian": "jacobian", "drift": "needs_projection", "state_jacobian": "jacobian"}


def _check_inherited(cls: type[Component]) -> None:
    """A subclass that inherits ``native`` but overrides a method its kernels stand for would run
    its parent's kernels in C and its own method in Python: refuse it."""
    owner = next(c for c in cls.__mro__ if "native" in vars(c))
    for role in cls.native.kernels():
        method = _METHODS[role]
        if getattr(cls, method) is not getattr(owner, method):
            raise CodegenError(f"{cls.__name__} overrides {method}() but inherits {owner.__name__}'s compiled "
                               f"kernels, which stand for {owner.__name__}.{method}(): declare its own `native = "
                               f"NativeKernels(...)`, or `native = None` to run its Python methods")


def _check_step(cls: type[Component]) -> None:
    """A compiled step (event update) is the whole of fmi2DoStep (fmi2NewDiscreteStates): it must
    leave nothing for an evaluation after it to compute (no states, no event indicators, every
    output among its returns)."""
    layout = cls._layout
    for role in ("step", "update"):
        kernel = getattr(cls.native, role)
        if kernel is None:
            continue
        if layout.nx or cls.n_event_indicators:
            raise CodegenError(f"{cls.__name__}.native: a {role} kernel is for components without states or event "
                               f"indicators (a sampled controller, a reference); this one integrates: declare its "
                               f"derivatives kernel instead")
        if cls.outputs is not Component.outputs:
            missing = [d.name for d in layout.declarations if d.causality == "output" and d.name not in kernel.returns]
            if missing:
                raise CodegenError(f"{cls.__name__}.native: its outputs() computes {', '.join(missing)} after "
                                   f"{'a step' if role == 'step' else 'an event'}, which the {role} kernel does not "
                                   f"return: add them to its returns")


#: each class's generated kernels (with the ``native`` they were made from), translated once per
#: process: the builds of one model (FMI 2.0 and 3.0, plain and portable) share its translation
_GENERATED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
#: the same for the classes of component files, which each build imports anew (a module named
#: after the file's content, see ``packager.load_component_class``): by module and class name
_GENERATED_FROM_FILES: dict = {}


def _generated_once(cls: type[Component]) -> Optional[GeneratedKernels]:
    """:func:`generate_component` of ``cls``, remembered for this process (a translation that fails
    is not remembered: it fails again, saying why)."""
    from_file = cls.__module__.startswith("_deltafmi_source_")
    memo, key = (_GENERATED_FROM_FILES, (cls.__module__, cls.__qualname__)) if from_file else (_GENERATED, cls)
    native = getattr(cls, "native", None)
    known = memo.get(key)
    if known is None or (not from_file and known[0] is not native):
        known = (native, generate_component(cls))
        memo[key] = known
    generated = known[1]
    return None if generated is None else GeneratedKernels(generated.source, copy.deepcopy(generated.description))


def component_library(cls: type[Component]) -> Optional[ComponentLibrary]:
    """``cls``'s kernels compiled (from the cache when built before), or None: none declared, or
    (``mode="fallback"``) they cannot be translated, with a warning naming the line.

    Raises :class:`BuildError` for ``mode="required"`` when they cannot be translated."""
    try:
        generated = _generated_once(cls)
    except CodegenError as exc:
        if cls.native.mode != "fallback":
            raise BuildError(f"{cls.__name__}: native kernels: {exc} (NativeKernels(mode=\"fallback\") ships "
                             f"Python instead)") from None
        warnings.warn(f"{cls.__name__}: its kernels stay Python (NativeKernels mode 'fallback'): {exc}", stacklevel=2)
        return None
    if generated is None:
        return None
    digest = hashlib.sha256(generated.source.encode()).hexdigest()[:16]
    folder = cache_dir() / "kernels-c" / digest
    if not folder.exists():  # written whole, then moved into place: parallel builds race harmlessly
        build_into(folder, lambda tmp: Path(tmp, f"{cls.fmi_model_name()}_kernels.c").write_text(generated.source))
    source = folder / f"{cls.fmi_model_name()}_kernels.c"
    try:
        library = single_file_library(source, f"{source.stem}.so", flags=CFLAGS, libraries=["-lm"])
    except NoCompilerError as exc:  # the same numbers from the Python methods, slower
        warnings.warn(f"{cls.__name__}: FMUs ship its Python methods instead of its compiled kernels (same "
                      f"results, slower): {exc}", stacklevel=2)
        return None
    return ComponentLibrary(library, source, generated.description)


def use_compiled_functions(cls: type[Component]) -> bool:
    """Compile ``cls``'s kernels (from the cache when built before) and have its instances made from
    now on in this process call the compiled functions it declares (``self.native_functions``),
    as they do in its FMU: for tests, benchmarks and anything that runs the component directly.
    False (its instances run the Python functions) when it declares none or no compiler is there
    (a warning says so); BuildError as :func:`component_library`."""
    kernels = component_library(cls)
    if kernels is None or not kernels.description.get("functions"):
        register_library(cls, None)
        return False
    register_library(cls, kernels.library, kernels.description)
    return True


def _attribute_type(cls: type, name: str, spec: Any) -> Any:
    scalars = {float: D, int: I, bool: B, str: S}
    if spec in scalars:
        return scalars[spec]
    if isinstance(spec, (Tup, Opt, Obj)) or spec in (D, I, B):
        return spec
    if dataclasses.is_dataclass(spec):
        return Obj(spec)
    try:  # a NamedTuple class, Optional[...], tuple[float, float, ...]
        return _type_of_hint(spec, f"{cls.__name__}.native: attribute {name!r}")
    except CodegenError:
        raise CodegenError(f"{cls.__name__}.native: attribute {name!r}: {spec!r} is not a dataclass of floats, a "
                           f"NamedTuple class, a fixed-size tuple, Optional of one, float, int, bool or str") from None


def _argument(cls: type[Component], role: str, name: str, attributes: dict) -> tuple[Any, str]:
    """(kernel type, C expression) of argument ``name``."""
    layout = cls._layout
    if name == "t":
        return D, "time"
    if name == "h" and role == "step":
        return D, "h"
    if name == "states":
        return Vec(layout.nx), f"real + {layout.x_offset}"
    if name in attributes:
        t, field = attributes[name], field_name(name)
        if isinstance(t, Tup) and t.homogeneous:
            return t, f"a->{field}.v"
        if isinstance(t, Opt) and isinstance(t.inner, Tup) and t.inner.homogeneous:
            return t, f"(a->{field}.some ? a->{field}.v.v : NULL)"
        if isinstance(t, (Tup, Opt, Obj)):
            return t, f"&a->{field}"
        return t, f"a->{field}"
    decl = {d.name: d for d in layout.declarations}.get(name)
    if decl is None:
        raise CodegenError(f"{cls.__name__}.native: {role} argument {name!r} is neither 't', 'states', "
                           + ("'h', " if role == "step" else "")
                           + f"a variable nor one of the attributes ({', '.join(attributes) or 'none declared'})")
    if decl.type is float:
        return (D, f"real[{decl.offset}]") if decl.shape is None else (Vec(decl.size), f"real + {decl.offset}")
    if decl.type is str or decl.shape is not None:
        raise CodegenError(f"{cls.__name__}.native: {role} argument {name!r}: kernels take Real variables, "
                           f"scalar Integer/Boolean ones and attributes, not this {decl.type.__name__} variable")
    return (B if decl.type is bool else I), f"ints[{decl.offset}]"


def _function_argument(cls: type, name: str, k: int, spec: Any) -> Any:
    """The kernel type of argument ``k`` of function ``name``, from its declared type."""
    if isinstance(spec, int) and not isinstance(spec, bool):
        if spec < 1:
            raise CodegenError(f"{cls.__name__}.native.functions[{name!r}]: argument {k}: {spec} floats (at least 1)")
        return Vec(spec)
    t = _attribute_type(cls, f"functions[{name!r}] argument {k}", spec)
    if t == S or _has_optional(t):
        raise CodegenError(f"{cls.__name__}.native.functions[{name!r}]: argument {k}: {spec!r}: functions take "
                           f"floats, ints, bools, n floats, dataclasses of floats, NamedTuples and tuples of these")
    return t


def _has_optional(t: Any) -> bool:
    if isinstance(t, Opt):
        return True
    return isinstance(t, Tup) and any(_has_optional(item) for item in t.items)


def _function_glue(cls: type, name: str, func: Any, types: list, result: Any) -> tuple[str, dict]:
    """The exported entry of function ``name`` and its description (see
    deltafmi/runtime/native_functions.py): the arguments as the generated entry takes them, the
    result's numbers flattened into ``values``."""
    where = f"{cls.__name__}.native.functions[{name!r}] ({func.__qualname__})"
    params, codes, args = [], [], []
    for k, t in enumerate(types):
        if isinstance(t, Tup) and t.homogeneous:
            params.append(f"const double *a{k}")
            args.append({"floats": len(t.items)})
        elif isinstance(t, Obj):
            params.append(f"const void *a{k}")  # the entry's own struct type, laid out as the description's
            args.append({"struct": describe(t)})
        elif isinstance(t, Tup):
            params.append(f"const void *a{k}")
            args.append({"struct": describe(t)})
        else:
            params.append(f"{'double' if t == D else 'int'} a{k}")
            args.append(describe(t))
        codes.append(f"a{k}")
    if result in (D, I, B):
        declare, out, leaves, described = "double out;" if result == D else "int out;", "&out", [("out", result)], \
            describe(result)
    elif isinstance(result, Tup) and result.homogeneous:
        declare, out = f"double out[{len(result.items)}];", "out"
        leaves = [(f"out[{k}]", D) for k in range(len(result.items))]
        described = {"floats": len(leaves)}
    else:
        declare, out = f"dfn_{name}_result out;", "&out"
        leaves = _leaves(result, "out", where)
        described = {"floats": len(leaves)}
    stores = "".join(f"    values[{k}] = {code};\n" for k, (code, _) in enumerate(leaves))
    code = (f"/* function {name}: {func.__module__}.{func.__qualname__} */\n"
            f"{EXPORT} int dfmi_function_{name}({', '.join([*params, 'double *values'])})\n{{\n"
            f"    {declare}\n    int err = dfn_{name}({', '.join([*codes, out])});\n    if (err) return err;\n"
            f"{stores}    return 0;\n}}\n")
    return code, {"args": args, "result": described}


def _leaves(t: Any, code: str, where: str) -> list[tuple[str, Any]]:
    """The scalars of a result of type ``t`` held in C expression ``code``, flattened in order."""
    if t in (D, I, B):
        return [(code, t)]
    if isinstance(t, Tup) and t.uniform:
        return [leaf for k, item in enumerate(t.items) for leaf in _leaves(item, f"{code}.v[{k}]", where)]
    if isinstance(t, Tup):
        names = t.names or tuple(f"f{k}" for k in range(len(t.items)))
        return [leaf for name, item in zip(names, t.items) for leaf in _leaves(item, f"{code}.{name}", where)]
    raise CodegenError(f"{where}: a kernel's result must be numbers or fixed-length tuples of them, not {t!r}")


def _targets(cls: type[Component], role: str, kernel: Kernel) -> list[tuple[str, bool]]:
    """(C lvalue, holds a float) of each scalar the kernel's result is written to."""
    layout = cls._layout
    if role in ("derivatives", "event_indicators"):
        if kernel.returns:
            raise CodegenError(f"{cls.__name__}.native: {role} are written to their own buffer; "
                               f"drop returns={kernel.returns!r}")
        if role == "event_indicators":
            return [(f"indicators[{k}]", True) for k in range(cls.n_event_indicators)]
        return [(f"real[{layout.dx_offset + k}]", True) for k in range(layout.nx)]
    if role == "drift":
        if kernel.returns:
            raise CodegenError(f"{cls.__name__}.native: a drift kernel returns whether the states drifted (a bool); "
                               f"drop returns={kernel.returns!r}")
        return [("drifted[0]", True)]
    declarations = {d.name: d for d in layout.declarations}
    if role == "project":
        if not kernel.returns:
            return [(f"real[{layout.x_offset + k}]", True) for k in range(layout.nx)]
        others = [name for name in kernel.returns if not isinstance(declarations.get(name), State)]
        if others:
            raise CodegenError(f"{cls.__name__}.native: project returns {', '.join(map(repr, others))}, which "
                               f"{'is not a state' if len(others) == 1 else 'are not states'}: a projection "
                               f"changes states only")
    targets = []
    for name in kernel.returns:
        decl = declarations.get(name)
        if decl is None or decl.type is str:
            raise CodegenError(f"{cls.__name__}.native: {role} returns {name!r}, which is not a Real, Integer or "
                               f"Boolean variable")
        buffer = "real" if decl.type is float else "ints"
        targets += [(f"{buffer}[{decl.offset + k}]", decl.type is float) for k in range(decl.size)]
    return targets


def _updates(cls: type[Component], role: str, kernel: Kernel, result: Any, attributes: dict,
             where: str) -> tuple[list[str], list[str], Any]:
    """A step or update kernel's result: (C statements that check its defer flag, C statements
    that store its updates (and an update's next time event), the type of the rest: the outputs)."""
    n = len(kernel.updates) + kernel.defer + (role == "update")
    if not n:
        return [], [], result
    if not isinstance(result, Tup) or result.uniform or result.names or len(result.items) < n:
        raise CodegenError(f"{where}: the result must be a tuple (*updates{', defer flag' if kernel.defer else ''}"
                           f"{', next time event' if role == 'update' else ''}, *outputs)")
    stores = []
    for k, name in enumerate(kernel.updates):
        if name not in attributes:
            raise CodegenError(f"{cls.__name__}.native: step updates {name!r}, which is not one of the attributes")
        if result.items[k] != attributes[name]:
            raise CodegenError(f"{where}: result item {k} ({result.items[k]!r}) is not the type of {name!r}")
        stores.append(f"    a->{field_name(name)} = out.f{k};")
    checks = []
    if kernel.defer:
        flag = len(kernel.updates)
        if result.items[flag] not in (I, B):
            raise CodegenError(f"{where}: result item {flag} (the defer flag) must be an int or a bool")
        checks.append(f"    if (out.f{flag}) return -1; /* to Python: it does what C cannot */")
    if role == "update":
        if result.items[n - 1] not in (D, I):
            raise CodegenError(f"{where}: result item {n - 1} (the next time event, nan for none) must be a float")
        stores.append(f"    *next_event_time = out.f{n - 1};")
    rest = Tup(result.items[n:])
    return checks, stores + (["    a->changed = 1;"] if kernel.updates else []), rest


def _glue(cls: type[Component], role: str, kernel: Kernel, args: list, result: Any, attributes: dict) -> str:
    where = f"{cls.__name__}.native.{role} ({kernel.func.__qualname__})"
    floats_out = role in ("jacobian", "state_jacobian")
    targets = [] if floats_out else _targets(cls, role, kernel)
    checks, updates, outputs = _updates(cls, role, kernel, result, attributes, where)
    if result == D:
        declare, out, leaves = "double out;", "&out", [("out", D)]
    elif isinstance(result, Tup) and result.homogeneous:
        declare, out = f"double out[{len(result.items)}];", "out"
        leaves = [(f"out[{k}]", D) for k in range(len(result.items))]
    else:
        first = len(kernel.updates) + kernel.defer + (role == "update")
        declare, out = f"dfk_{role}_result out;", "&out"
        leaves = [leaf for k, item in enumerate(outputs.items) for leaf in _leaves(item, f"out.f{first + k}", where)] \
            if first else _leaves(result, "out", where)
    if floats_out:  # floats for Python or CVODE (the caller's array), not variables
        if any(t != D for _, t in leaves):
            raise CodegenError(f"{where}: a {role} kernel returns floats only")
        nx = cls._layout.nx
        if role == "state_jacobian" and len(leaves) != nx * nx:
            raise CodegenError(f"{where}: a state_jacobian kernel returns nx * nx = {nx * nx} floats "
                               f"(d derivatives / d states, column by column), this one {len(leaves)}")
        targets = [(f"values[{k}]", True) for k in range(len(leaves))]
    if len(leaves) != len(targets):
        raise CodegenError(f"{where}: the kernel returns {len(leaves)} numbers for {len(targets)} scalars")
    stores = []
    for (target, is_float), (code, t) in zip(targets, leaves):
        if not is_float and t == D:
            raise CodegenError(f"{where}: a float result goes to the Integer/Boolean scalar {target}")
        stores.append(f"    {target} = {code};")
    call = ", ".join([code for t, code in args if t != NONE] + [out])
    changes = role in ("step", "update")
    results = [*kernel.updates, *(["(defer)"] if kernel.defer else []),
               *(["(next time event)"] if role == "update" else []), *kernel.returns]
    last = {"step": "double h, double *real, int *ints", "update": "double *real, int *ints, double *next_event_time",
            "jacobian": "double *real, int *ints, double *values",
            "state_jacobian": "double *real, int *ints, double *values", "drift": "double *real, int *ints, double *drifted"}
    return (f"/* {role}: {kernel.func.__qualname__}({', '.join(kernel.args)})"
            + (f" -> {', '.join(results)}" if results else "") + " */\n"
            f"{EXPORT} int dfmi_kernel_{role}({'' if changes else 'const '}void *attributes, double time, "
            + last.get(role, "double *real, int *ints, double *indicators") + ")\n{\n"
            f"    {'' if changes else 'const '}DfmiAttributes *a = attributes;\n    (void)a; (void)time; (void)ints;"
            + ("" if role in last else " (void)indicators;") + "\n"
            f"    {declare}\n    int err = dfk_{role}({call});\n    if (err) return err;\n"
            + "".join(line + "\n" for line in checks + updates + stores) + "    return 0;\n}\n")
