"""Translate typed float kernels (Python functions) into C: a prototype for issue 26 item 1.

The subset: float locals and arithmetic (+ - * / **, unary -, comparisons, and/or/not), fixed-length
tuples and lists of floats (literals, constant indexing and slicing, concatenation, unpacking),
``math`` functions, reads of a parameter object's float fields (``p.l1`` -> ``p->l1`` on a C
struct generated from the dataclass), module-level float/tuple constants (their values taken at
generation time), calls to other kernels (any module: each is specialized on its argument types,
as a static C function, inlined), ``for`` over ``range`` with constant bounds, ``if``, and ``raise`` (an
error code, the raising line, returned by the entry). Anything else is a :class:`CodegenError`
naming the file and line.

Every Python float operation becomes the same C double operation in the same order (the emitted
C parenthesizes the AST; ``**`` is libm's ``pow``, as CPython's float power), so with
``-ffp-contract=off -fno-builtin-pow`` the results are bit for bit those of the Python source.
Tuples become C structs passed by value; the C compiler keeps them in registers.

Usage: ``generate([Entry("dfk_state_derivative", dynamics.state_derivative, [Obj(DeltaParams),
Vec(18), Vec(3), Vec(3), D])], identities={"_as_list"})`` returns a C translation unit whose entry
``int dfk_state_derivative(const DeltaParams *p, const double *x, const double *u,
const double *f, double pole, double out[18])`` returns 0 or the line of the ``raise`` taken.
"""
from __future__ import annotations

import ast
import dataclasses
import inspect
import math
import textwrap
import types
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Optional


class CodegenError(Exception):
    """A construct the generator cannot translate; the message names file:line."""


@dataclass(frozen=True)
class Scalar:
    c: str  #: "double", "int" (loop counters, integer constants) or "bool" (conditions)


D, I, B = Scalar("double"), Scalar("int"), Scalar("bool")


@dataclass(frozen=True)
class Tup:
    items: tuple  #: element types

    @property
    def homogeneous(self) -> bool:
        return all(t == D for t in self.items)


def Vec(n: int) -> Tup:
    """A fixed-length float sequence (tuple or list) of ``n`` elements."""
    return Tup((D,) * n)


@dataclass(frozen=True)
class Obj:
    cls: type  #: a dataclass whose fields are all floats, passed as ``const Struct *``


@dataclass
class Entry:
    """An exported C function: ``c_name`` runs ``func`` specialized on ``args``."""

    c_name: str
    func: Callable
    args: list


_MATH = {"sin": 1, "cos": 1, "tan": 1, "asin": 1, "acos": 1, "atan": 1, "atan2": 2, "sqrt": 1,
         "exp": 1, "log": 1, "fabs": 1, "hypot": 2, "tanh": 1, "sinh": 1, "cosh": 1}
_BINOPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/"}
_CMPOPS = {ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">=", ast.Eq: "==", ast.NotEq: "!="}


class _Unit:
    """The translation unit: struct types, constants, specialized functions."""

    def __init__(self, identities: Iterable[str]) -> None:
        self.identities = set(identities)
        self.structs: dict[Any, str] = {}
        self.struct_defs: list[str] = []
        self.constants: dict[int, tuple[str, Any]] = {}
        self.const_defs: list[str] = []
        self.functions: dict[tuple, tuple[str, Any]] = {}
        self.function_defs: list[str] = []
        self.prototypes: list[str] = []
        self.in_progress: set = set()
        self.counter = 0

    def ctype(self, t: Any) -> str:
        if isinstance(t, Scalar):
            return "double" if t == D else "int"
        if isinstance(t, Obj):
            return f"const {self.obj_struct(t.cls)} *"
        if t not in self.structs:
            if t.homogeneous:
                body = f"double v[{len(t.items)}];"
            else:  # element types first: their typedefs precede this one
                body = " ".join(f"{self.ctype(item)} f{k};" for k, item in enumerate(t.items))
            name = f"T{len(self.structs)}"
            self.structs[t] = name
            self.struct_defs.append(f"typedef struct {{ {body} }} {name};")
        return self.structs[t]

    def obj_struct(self, cls: type) -> str:
        if cls not in self.structs:
            fields = dataclasses.fields(cls)
            self.structs[cls] = cls.__name__
            self.struct_defs.append(f"typedef struct {{ {' '.join(f'double {f.name};' for f in fields)} }} "
                                    f"{cls.__name__};")
        return self.structs[cls]

    def constant(self, name: str, value: Any, where: str) -> tuple[str, Any]:
        if id(value) not in self.constants:
            t = _type_of_value(value, where)
            cname = f"g_{name}_{len(self.constants)}"
            self.constants[id(value)] = (cname, t)
            self.const_defs.append(f"static const {self.ctype(t)} {cname} = {_initializer(value)};")
        return self.constants[id(value)]

    def specialize(self, func: Callable, args: tuple, where: str) -> tuple[str, Any]:
        key = (func, args)
        if key in self.functions:
            return self.functions[key]
        if key in self.in_progress:
            raise CodegenError(f"{where}: recursion ({func.__name__}) is not supported")
        self.in_progress.add(key)
        self.counter += 1
        name = f"k_{func.__name__.lstrip('_')}_{self.counter}"
        fn = _Function(self, func, args, name)
        self.functions[key] = (name, fn.ret)
        self.prototypes.append(fn.prototype + ";")
        self.function_defs.append(fn.code)
        self.in_progress.discard(key)
        return name, fn.ret


def _type_of_value(value: Any, where: str) -> Any:
    if isinstance(value, float):
        return D
    if isinstance(value, tuple):
        return Tup(tuple(_type_of_value(v, where) for v in value))
    raise CodegenError(f"{where}: a module constant must be a float or a tuple of floats, not "
                       f"{type(value).__name__}")


def _initializer(value: Any) -> str:
    if isinstance(value, float):
        return _float(value)
    inner = ", ".join(_initializer(v) for v in value)
    homogeneous = all(isinstance(v, float) for v in value)
    return f"{{{{{inner}}}}}" if homogeneous else f"{{{inner}}}"


def _float(v: float) -> str:
    if not math.isfinite(v):
        raise CodegenError(f"non-finite constant {v!r}")
    text = repr(float(v))  # shortest round-trip form: C's strtod reads back the same double
    return text if any(c in text for c in ".e") else text + ".0"


class _Function:
    """One function specialized on its argument types, translated statement by statement."""

    def __init__(self, unit: _Unit, func: Callable, args: tuple, name: str) -> None:
        self.unit, self.func, self.cname = unit, func, name
        self.file = inspect.getsourcefile(func) or "<unknown>"
        lines, first = inspect.getsourcelines(func)
        tree = ast.parse(textwrap.dedent("".join(lines)))
        ast.increment_lineno(tree, first - 1)
        node = tree.body[0]
        if not isinstance(node, ast.FunctionDef):
            raise CodegenError(f"{self.file}:{first}: {func.__name__} is not a plain function")
        self.node = node
        self.globals = func.__globals__
        self.locals: dict[str, Any] = {}
        self.temps: list[tuple[str, Any]] = []
        self.ret: Optional[Any] = None
        params = [a.arg for a in node.args.args]
        if node.args.vararg or node.args.kwarg or node.args.kwonlyargs or len(args) != len(params):
            raise CodegenError(f"{self.where(node)}: {func.__name__}: only positional parameters "
                               f"(no *args, **kwargs, keyword-only), {len(params)} of them (got {len(args)} types)")
        for pname, t in zip(params, args):
            self.locals[pname] = t
        body: list[str] = []
        self.block(node.body, body, 1)
        if self.ret is None:
            raise CodegenError(f"{self.where(node)}: {func.__name__} returns nothing")
        ret_c = unit.ctype(self.ret)
        zero = "0.0" if self.ret == D else f"({ret_c}){{0}}"
        signature = ", ".join(["int *err"] + [f"{unit.ctype(t)} v_{p}" for p, t in zip(params, args)])
        self.prototype = f"KERNEL {ret_c} {name}({signature})"
        decls = [f"    {unit.ctype(t)} v_{n};" for n, t in self.locals.items() if n not in params]
        decls += [f"    {unit.ctype(t)} {n};" for n, t in self.temps]
        text = "\n".join(body).replace("@ZERO@", zero)
        self.code = (f"/* {func.__module__}.{func.__qualname__} ({self.file}:{node.lineno}) */\n"
                     f"{self.prototype}\n{{\n" + "\n".join(decls) + ("\n" if decls else "") + text + "\n}\n")

    # --- helpers ------------------------------------------------------------------------------
    def where(self, node: ast.AST) -> str:
        return f"{self.file}:{getattr(node, 'lineno', '?')}"

    def fail(self, node: ast.AST, what: str) -> CodegenError:
        return CodegenError(f"{self.where(node)}: in {self.func.__name__}: {what}")

    def temp(self, t: Any, code: str, out: list[str], indent: int) -> str:
        name = f"t{len(self.temps)}"
        self.temps.append((name, t))
        out.append("    " * indent + f"{name} = {code};")
        return name

    def bind(self, node: ast.AST, name: str, t: Any) -> str:
        t = D if t == I else t
        if t == B:
            raise self.fail(node, "a comparison's result cannot be stored")
        old = self.locals.get(name)
        if old is not None and old != t:
            raise self.fail(node, f"'{name}' changes type")
        self.locals[name] = t
        return f"v_{name}"

    # --- statements ---------------------------------------------------------------------------
    def block(self, stmts: list, out: list[str], indent: int) -> None:
        for s in stmts:
            self.stmt(s, out, indent)

    def stmt(self, s: ast.stmt, out: list[str], ind: int) -> None:
        pad = "    " * ind
        if isinstance(s, ast.Expr):
            if isinstance(s.value, ast.Constant):
                return  # docstring
            code, _ = self.expr(s.value, out, ind)
            out.append(f"{pad}(void)({code});")
        elif isinstance(s, (ast.Assign, ast.AnnAssign)):
            targets = s.targets if isinstance(s, ast.Assign) else [s.target]
            if s.value is None or len(targets) != 1:
                raise self.fail(s, "only single assignments with a value are supported")
            self.assign(targets[0], s.value, out, ind)
        elif isinstance(s, ast.AugAssign):
            if not isinstance(s.target, ast.Name) or type(s.op) not in _BINOPS:
                raise self.fail(s, "augmented assignment only as name (+ - * /)= expression")
            code, t = self.expr(s.value, out, ind)
            if self.locals.get(s.target.id) != D or t not in (D, I):
                raise self.fail(s, "augmented assignment only on float locals")
            out.append(f"{pad}v_{s.target.id} {_BINOPS[type(s.op)]}= {code};")
        elif isinstance(s, ast.Return):
            if s.value is None:
                raise self.fail(s, "a kernel returns a value")
            code, t = self.expr(s.value, out, ind)
            t = D if t == I else t
            if self.ret is not None and self.ret != t:
                raise self.fail(s, "returns differ in type")
            self.ret = t
            out.append(f"{pad}return {code};")
        elif isinstance(s, ast.If):
            code, _ = self.expr(s.test, out, ind)
            out.append(f"{pad}if ({code}) {{")
            self.block(s.body, out, ind + 1)
            if s.orelse:
                out.append(f"{pad}}} else {{")
                self.block(s.orelse, out, ind + 1)
            out.append(f"{pad}}}")
        elif isinstance(s, ast.Raise):
            out.append(f"{pad}if (!*err) *err = {s.lineno};  /* {ast.unparse(s)[:60]} */")
            out.append(f"{pad}return @ZERO@;")
        elif isinstance(s, ast.For):
            self.for_range(s, out, ind)
        elif isinstance(s, ast.Pass):
            pass
        else:
            raise self.fail(s, f"statement '{type(s).__name__}' is not supported")

    def for_range(self, s: ast.For, out: list[str], ind: int) -> None:
        it = s.iter
        if not (isinstance(it, ast.Call) and isinstance(it.func, ast.Name) and it.func.id == "range"
                and isinstance(s.target, ast.Name) and not s.orelse and 1 <= len(it.args) <= 3):
            raise self.fail(s, "only 'for name in range(...)' loops are supported")
        bounds = []
        for a in it.args:
            code, t = self.expr(a, out, ind)
            if t != I:
                raise self.fail(s, "range() bounds must be integers")
            bounds.append(code)
        start, stop, step = (["0"] + bounds + ["1"])[-3:] if len(bounds) == 1 else (bounds + ["1"])[:3]
        if s.target.id in self.locals and self.locals[s.target.id] != I:
            raise self.fail(s, f"'{s.target.id}' changes type")
        self.locals[s.target.id] = I
        v = f"v_{s.target.id}"
        out.append(f"{'    ' * ind}for ({v} = {start}; {v} < {stop}; {v} += {step}) {{")
        self.block(s.body, out, ind + 1)
        out.append(f"{'    ' * ind}}}")

    def assign(self, target: ast.expr, value: ast.expr, out: list[str], ind: int) -> None:
        pad = "    " * ind
        if isinstance(target, ast.Name):
            code, t = self.expr(value, out, ind)
            if target.id == "_":
                return
            out.append(f"{pad}{self.bind(target, target.id, t)} = {code};")
        elif isinstance(target, (ast.Tuple, ast.List)):
            if isinstance(value, (ast.Tuple, ast.List)):
                if len(value.elts) != len(target.elts):
                    raise self.fail(target, "unpacking: lengths differ")
                parts = [self.expr(v, out, ind) for v in value.elts]  # all evaluated before any store
                parts = [(self.temp(D if t == I else t, c, out, ind), D if t == I else t) for c, t in parts]
            else:
                code, t = self.expr(value, out, ind)
                if not isinstance(t, Tup) or len(t.items) != len(target.elts):
                    raise self.fail(target, f"cannot unpack {len(target.elts)} values from this expression")
                src = code if code.isidentifier() else self.temp(t, code, out, ind)
                parts = [(_element(src, t, k), t.items[k]) for k in range(len(t.items))]
            for sub, (code, t) in zip(target.elts, parts):
                if isinstance(sub, ast.Name):
                    if sub.id != "_":
                        out.append(f"{pad}{self.bind(sub, sub.id, t)} = {code};")
                elif isinstance(sub, (ast.Tuple, ast.List)):
                    self.assign_from(sub, code, t, out, ind)
                else:
                    raise self.fail(sub, "only names and tuples of names can be assigned")
        else:
            raise self.fail(target, "only names and tuples of names can be assigned")

    def assign_from(self, target: ast.expr, code: str, t: Any, out: list[str], ind: int) -> None:
        if not isinstance(t, Tup) or len(t.items) != len(target.elts):
            raise self.fail(target, f"cannot unpack {len(target.elts)} values here")
        for k, sub in enumerate(target.elts):
            if isinstance(sub, ast.Name):
                if sub.id != "_":
                    out.append(f"{'    ' * ind}{self.bind(sub, sub.id, t.items[k])} = {_element(code, t, k)};")
            elif isinstance(sub, (ast.Tuple, ast.List)):
                self.assign_from(sub, _element(code, t, k), t.items[k], out, ind)
            else:
                raise self.fail(sub, "only names and tuples of names can be assigned")

    # --- expressions --------------------------------------------------------------------------
    def expr(self, e: ast.expr, out: list[str], ind: int) -> tuple[str, Any]:
        if isinstance(e, ast.Constant):
            if isinstance(e.value, bool) or not isinstance(e.value, (int, float)):
                raise self.fail(e, f"constant {e.value!r}: only int and float constants")
            return (str(e.value), I) if isinstance(e.value, int) else (_float(e.value), D)
        if isinstance(e, ast.Name):
            return self.name(e)
        if isinstance(e, ast.Attribute):
            return self.attribute(e)
        if isinstance(e, ast.BinOp):
            return self.binop(e, out, ind)
        if isinstance(e, ast.UnaryOp):
            code, t = self.expr(e.operand, out, ind)
            if isinstance(e.op, ast.Not):
                return f"(!{code})", B
            if isinstance(e.op, (ast.USub, ast.UAdd)) and t in (D, I):
                return f"({'-' if isinstance(e.op, ast.USub) else '+'}{code})", t
            raise self.fail(e, f"unary '{ast.unparse(e)}' is not supported")
        if isinstance(e, ast.Compare):
            if len(e.ops) != 1 or type(e.ops[0]) not in _CMPOPS:
                raise self.fail(e, "only single comparisons (< <= > >= == !=) are supported")
            (a, ta), (b, tb) = self.expr(e.left, out, ind), self.expr(e.comparators[0], out, ind)
            if {ta, tb} - {D, I}:
                raise self.fail(e, "comparisons only between numbers")
            return f"({a} {_CMPOPS[type(e.ops[0])]} {b})", B
        if isinstance(e, ast.BoolOp):
            op = " && " if isinstance(e.op, ast.And) else " || "
            return "(" + op.join(self.expr(v, out, ind)[0] for v in e.values) + ")", B
        if isinstance(e, (ast.Tuple, ast.List)):
            parts = [self.expr(v, out, ind) for v in e.elts]
            t = Tup(tuple(D if pt == I else pt for _, pt in parts))
            return self.literal(t, [c for c, _ in parts]), t
        if isinstance(e, ast.Subscript):
            return self.subscript(e, out, ind)
        if isinstance(e, ast.Call):
            return self.call(e, out, ind)
        raise self.fail(e, f"expression '{ast.unparse(e)[:50]}' ({type(e).__name__}) is not supported")

    def literal(self, t: Tup, codes: list[str]) -> str:
        inner = ", ".join(codes)
        return f"(({self.unit.ctype(t)}){{{{{inner}}}}})" if t.homogeneous else f"(({self.unit.ctype(t)}){{{inner}}})"

    def name(self, e: ast.Name) -> tuple[str, Any]:
        if e.id in self.locals:
            return f"v_{e.id}", self.locals[e.id]
        if e.id not in self.globals:
            raise self.fail(e, f"name '{e.id}' is not defined")
        value = self.globals[e.id]
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return (_float(value), D) if isinstance(value, float) else (str(value), I)
        if isinstance(value, tuple):
            return self.unit.constant(e.id, value, self.where(e))
        raise self.fail(e, f"global '{e.id}' ({type(value).__name__}) cannot be used as a value")

    def attribute(self, e: ast.Attribute) -> tuple[str, Any]:
        if isinstance(e.value, ast.Name) and e.value.id not in self.locals \
                and self.globals.get(e.value.id) is math and e.attr in ("pi", "e", "tau"):
            return _float(getattr(math, e.attr)), D
        if isinstance(e.value, ast.Name) and isinstance(self.locals.get(e.value.id), Obj):
            cls = self.locals[e.value.id].cls
            fields = {f.name for f in dataclasses.fields(cls)}
            if e.attr not in fields:
                raise self.fail(e, f"{cls.__name__} has no field '{e.attr}'")
            return f"v_{e.value.id}->{e.attr}", D
        raise self.fail(e, f"attribute '{ast.unparse(e)}' is not supported (parameter fields and math constants only)")

    def binop(self, e: ast.BinOp, out: list[str], ind: int) -> tuple[str, Any]:
        (a, ta), (b, tb) = self.expr(e.left, out, ind), self.expr(e.right, out, ind)
        if isinstance(e.op, ast.Add) and isinstance(ta, Tup) and isinstance(tb, Tup):
            a = a if a.isidentifier() else self.temp(ta, a, out, ind)
            b = b if b.isidentifier() else self.temp(tb, b, out, ind)
            t = Tup(ta.items + tb.items)
            codes = [_element(a, ta, k) for k in range(len(ta.items))] + \
                [_element(b, tb, k) for k in range(len(tb.items))]
            return self.literal(t, codes), t
        if isinstance(e.op, ast.Pow) and not {ta, tb} - {D, I} and D in (ta, tb):
            # Python's float ** number is C's pow on doubles (float_pow): the same value
            return f"pow({a}, (double)({b}))", D
        if type(e.op) not in _BINOPS or {ta, tb} - {D, I}:
            raise self.fail(e, f"operation '{ast.unparse(e)[:50]}' is not supported (+ - * / on floats, + on tuples)")
        if ta == I and tb == I:
            if isinstance(e.op, ast.Div):
                return f"((double)({a}) / (double)({b}))", D
            return f"({a} {_BINOPS[type(e.op)]} {b})", I
        return f"({a} {_BINOPS[type(e.op)]} {b})", D

    def subscript(self, e: ast.Subscript, out: list[str], ind: int) -> tuple[str, Any]:
        code, t = self.expr(e.value, out, ind)
        if not isinstance(t, Tup):
            raise self.fail(e, "only tuples and lists can be indexed")
        n = len(t.items)
        if isinstance(e.slice, ast.Slice):
            bounds = []
            for b, default in ((e.slice.lower, 0), (e.slice.upper, n)):
                if b is None:
                    bounds.append(default)
                    continue
                k = _const_int(b)
                if k is None:
                    raise self.fail(e, "slice bounds must be integer constants (the length is fixed)")
                bounds.append(max(0, min(n, k + n if k < 0 else k)))
            if e.slice.step is not None:
                raise self.fail(e, "slices with a step are not supported")
            src = code if code.isidentifier() else self.temp(t, code, out, ind)
            sub = Tup(t.items[bounds[0]:bounds[1]])
            return self.literal(sub, [_element(src, t, k) for k in range(bounds[0], bounds[1])]), sub
        k = _const_int(e.slice)
        if k is not None:
            if not -n <= k < n:
                raise self.fail(e, f"index {k} out of range for {n} elements")
            return _element(code, t, k % n), t.items[k % n]
        index, ti = self.expr(e.slice, out, ind)
        if ti != I or not t.homogeneous:
            raise self.fail(e, "a variable index needs an int and a float sequence")
        return f"{code}.v[{index}]", D

    def call(self, e: ast.Call, out: list[str], ind: int) -> tuple[str, Any]:
        f = e.func
        if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and self.globals.get(f.value.id) is math:
            if _MATH.get(f.attr) != len(e.args) or e.keywords:
                raise self.fail(e, f"math.{f.attr} with {len(e.args)} arguments is not supported")
            args = [self.expr(a, out, ind) for a in e.args]
            if any(t not in (D, I) for _, t in args):
                raise self.fail(e, f"math.{f.attr} takes floats")
            return f"{f.attr}({', '.join(c if t == D else f'(double)({c})' for c, t in args)})", D
        if not isinstance(f, ast.Name) or f.id in self.locals:
            raise self.fail(e, f"call '{ast.unparse(f)}' is not supported")
        if f.id in ("float", "abs") or f.id in self.unit.identities:
            if len(e.args) != 1 or e.keywords:
                raise self.fail(e, f"{f.id}() takes one argument here")
            code, t = self.expr(e.args[0], out, ind)
            if f.id == "float":
                return (code, D) if t == D else (f"((double)({code}))", D)
            if f.id == "abs":
                return f"fabs({code})", D
            return code, t
        target = self.globals.get(f.id)
        if not isinstance(target, types.FunctionType):
            raise self.fail(e, f"call to '{f.id}' is not supported (kernels, math.* and float() only)")
        sig = inspect.signature(target)
        try:
            bound = sig.bind(*e.args, **{k.arg: k.value for k in e.keywords})
        except TypeError as exc:
            raise self.fail(e, f"{f.id}(): {exc}") from None
        codes, arg_types = [], []
        for pname, param in sig.parameters.items():
            if pname in bound.arguments:
                code, t = self.expr(bound.arguments[pname], out, ind)
            elif isinstance(param.default, (int, float)) and not isinstance(param.default, bool):
                code, t = _float(float(param.default)), D
            else:
                raise self.fail(e, f"{f.id}(): parameter '{pname}' has no float default")
            if t == I:
                code, t = f"((double)({code}))", D
            codes.append(code)
            arg_types.append(t)
        name, ret = self.unit.specialize(target, tuple(arg_types), self.where(e))
        return f"{name}({', '.join(['err'] + codes)})", ret


def signature_of(func: Callable) -> list:
    """Argument types of ``func`` from its annotations: float -> D, a tuple of floats (or of such
    tuples) -> Tup, a dataclass of floats -> Obj. CodegenError for any other annotation (e.g. a
    list or a Sequence, whose length the C side must know)."""
    import typing

    where = f"{inspect.getsourcefile(func)}:{func.__code__.co_firstlineno}"
    try:
        hints = typing.get_type_hints(func)
    except Exception as exc:  # noqa: BLE001 (unresolvable annotations: report them)
        raise CodegenError(f"{where}: {func.__name__}: annotations not resolvable ({exc})") from None

    def convert(name: str, hint: Any) -> Any:
        if hint is float:
            return D
        if dataclasses.is_dataclass(hint) and all(f.type in (float, "float") for f in dataclasses.fields(hint)):
            return Obj(hint)
        if typing.get_origin(hint) is tuple and Ellipsis not in typing.get_args(hint):
            return Tup(tuple(convert(name, h) for h in typing.get_args(hint)))
        what = "not annotated" if hint is None else repr(hint)
        raise CodegenError(f"{where}: {func.__name__}: parameter '{name}' is {what}; kernels take "
                           f"float, fixed-length tuples of floats, or a dataclass of floats")

    params = inspect.signature(func).parameters
    return [convert(name, hints.get(name)) for name in params]


def _element(code: str, t: Tup, k: int) -> str:
    return f"{code}.v[{k}]" if t.homogeneous else f"{code}.f{k}"


def _const_int(node: ast.expr) -> Optional[int]:
    if isinstance(node, ast.Constant) and isinstance(node.value, int) and not isinstance(node.value, bool):
        return node.value
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        k = _const_int(node.operand)
        return None if k is None else -k
    return None


def generate(entries: list[Entry], identities: Iterable[str] = ()) -> str:
    """One C translation unit with ``entries`` exported (see the module docstring).

    ``identities``: names of helper functions taken as the identity on their one argument (e.g.
    a list conversion that the fixed-length arrays make unnecessary).
    """
    unit = _Unit(identities)
    wrappers = []
    for entry in entries:
        where = f"{inspect.getsourcefile(entry.func)}:{entry.func.__code__.co_firstlineno}"
        name, ret = unit.specialize(entry.func, tuple(entry.args), where)
        params, call = ["int err = 0;"], []
        cparams = []
        for pname, t in zip(inspect.signature(entry.func).parameters, entry.args):
            if isinstance(t, Tup):
                if not t.homogeneous:
                    raise CodegenError(f"{where}: entry arguments are floats, float arrays or objects")
                cparams.append(f"const double *{pname}")
                params.append(f"{unit.ctype(t)} a_{pname}; memcpy(a_{pname}.v, {pname}, sizeof a_{pname}.v);")
                call.append(f"a_{pname}")
            else:
                cparams.append(f"{unit.ctype(t)} {pname}")
                call.append(pname)
        if ret == D:
            cparams.append("double *out")
            store = "*out = r;"
        elif isinstance(ret, Tup) and ret.homogeneous:
            cparams.append(f"double out[{len(ret.items)}]")
            store = "memcpy(out, r.v, sizeof r.v);"
        else:
            raise CodegenError(f"{where}: an entry returns a float or a float sequence")
        wrappers.append(f"int {entry.c_name}({', '.join(cparams)})\n{{\n    "
                        + "\n    ".join(params)
                        + f"\n    {unit.ctype(ret)} r = {name}({', '.join(['&err'] + call)});\n    {store}\n"
                        f"    return err;\n}}\n")
    head = ("/* Generated by benchmarks/kernel_codegen from the Python kernels named below; do not edit.\n"
            " * Compile with -ffp-contract=off -fno-builtin-pow (no fused multiply-add, pow(x, 2.0) not\n"
            " * folded to x * x): bit for bit with the Python. */\n"
            "#include <math.h>\n#include <string.h>\n\n"
            "/* Kernels are inlined into the entry: small structs then stay in registers (measured:\n"
            " * 0.89x the hand-written C's time, against 1.12x as plain static functions) */\n"
            "#if defined(__GNUC__)\n#define KERNEL static inline __attribute__((always_inline))\n"
            "#else\n#define KERNEL static inline\n#endif\n")
    return "\n".join([head, *unit.struct_defs, "", *unit.const_defs, "", *unit.prototypes, "",
                      *unit.function_defs, *wrappers])
