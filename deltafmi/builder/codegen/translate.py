"""Translate typed float kernels (Python functions) into C: the code generator of issue 26.

The subset: float, int and bool locals and arithmetic (+ - * / **, unary -, comparisons,
and/or/not, | & on ints), fixed-length tuples and lists (literals, indexing and slicing,
concatenation, repetition by a constant, unpacking, ``append`` and ``+=`` on lists: every
length is known when the C is generated, so a list is a C struct), ``math`` functions and
constants, ``min``/``max``/``abs``/``float``/``tuple``/``list``/``len``, ``any``/``all``/``sum``
over generator expressions and list comprehensions over fixed-length sequences (unrolled),
``bisect.bisect_right`` over a float sequence (``lo`` and ``hi`` too), ``None`` and Optional values (``x is None``; a C
struct with a flag), NamedTuples and dataclass-like objects as parameters (their int, bool, str,
float, tuple and Optional fields), NamedTuple construction, reads of a parameter object's float fields
(``p.l1`` -> ``p->l1`` on a C struct generated from the dataclass), module-level int/float/tuple
constants (their values taken at generation time), calls to other kernels (any module: each is
specialized on its argument types, as a static C function, inlined), ``for`` over ``range``
(unrolled when the bounds are constants, a C loop otherwise), over ``zip`` of sequences and over
a sequence (unrolled), ``while``, ``break``/``continue`` (in C loops), ``if``/``else``,
conditional expressions, and ``raise`` (an error code, the raising line, returned by the entry). Anything else is a :class:`CodegenError` naming the
file and line.

Every Python float operation becomes the same C double operation in the same order (the emitted
C parenthesizes the AST; ``**`` is libm's ``pow``, as CPython's float power; ``min``/``max`` keep
Python's first-argument-on-ties), so with ``-ffp-contract=off -fno-builtin-pow`` the results are
bit for bit those of the Python source. Tuples become C structs passed by value; the C compiler
keeps them in registers.

Lists are values: ``append`` and ``+=`` rebind the name to a longer sequence, so another name
bound to the same list does not see the change (kernels do not share lists; a kernel that relied
on it would differ from the Python). A name may change type (a list that grows): each (name,
type) is its own C variable. Where
control flow joins, a name that holds None on one side and a value on the other becomes
Optional; other disagreements are an error where the name is read.

Usage: ``generate([Entry("dfk_state_derivative", dynamics.state_derivative, [Obj(DeltaParams),
Vec(18), Vec(3), Vec(3), D])], identities={"_as_list"})`` returns a C translation unit whose entry
``int dfk_state_derivative(const DeltaParams *p, const double *x, const double *u,
const double *f, double pole, double out[18])`` returns 0 or the line of the ``raise`` taken.
Argument kinds: ``D``/``I``/``B`` scalars by value; ``Obj(dataclass)`` a ``const`` pointer to
its struct; ``Vec(n)`` ``const double *``; ``Opt(Vec(n))`` ``const double *`` (NULL for None);
``named(NamedTupleClass)`` and ``record(instance)`` a ``const`` pointer to their struct. The
result goes to the last parameter ``out`` (``double *``, ``double[n]`` or a pointer to the
result's struct, whose type is also named ``<entry>_result``).
"""
from __future__ import annotations

import ast
import dataclasses
import inspect
import math
import re
import sys
import textwrap
import types
import typing
from collections import Counter
from pathlib import Path
from typing import Any, Callable, Iterable, Optional

from .kernel_types import (NONE, B, CodegenError, D, Entry, Fn, I, Obj, Opt, Poison, S, Scalar, Tup,
                           _type_of_hint, _type_of_value, _unify)

__all__ = ["D", "I", "generate", "signature_of"]


_MATH = {"sin": 1, "cos": 1, "tan": 1, "asin": 1, "acos": 1, "atan": 1, "atan2": 2, "sqrt": 1,
         "exp": 1, "log": 1, "fabs": 1, "tanh": 1, "sinh": 1, "cosh": 1}
_MATH_BOOL = {"isfinite", "isnan", "isinf"}
_BINOPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/"}
_INTOPS = {ast.BitOr: "|", ast.BitAnd: "&"}
_CMPOPS = {ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">=", ast.Eq: "==", ast.NotEq: "!="}
_UNROLL_MAX = 64  #: a range with constant bounds up to this many iterations is unrolled


class _Unit:
    """The translation unit: struct types, constants, specialized functions."""

    def __init__(self, identities: Iterable[str]) -> None:
        self.identities = set(identities)
        self.structs: dict[Any, str] = {}
        self.struct_names: set[str] = set()
        self.struct_defs: list[str] = []
        self.constants: dict[int, tuple[str, Any]] = {}
        self.const_defs: list[str] = []
        self.functions: dict[tuple, tuple[str, Any]] = {}
        self.function_defs: list[str] = []
        self.prototypes: list[str] = []
        self.in_progress: set = set()
        self.counter = 0

    def _name(self, base: str) -> str:
        name, k = base, 1
        while name in self.struct_names:
            k += 1
            name = f"{base}_{k}"
        self.struct_names.add(name)
        return name

    def ctype(self, t: Any) -> str:
        if isinstance(t, Scalar):
            if t in (NONE,):
                raise CodegenError("None has no C type here")
            return {"double": "double", "str": "const char *"}.get(t.c, "int")
        if isinstance(t, Obj):
            return f"const {self.obj_struct(t.cls)} *"
        if t in self.structs:
            return self.structs[t]
        if isinstance(t, Opt):
            body = f"int some; {self.ctype(t.inner)} v;"
            name = self._name(f"O{len(self.structs)}")
        elif isinstance(t, Tup):
            if not t.items:
                raise CodegenError("an empty sequence has no C type")
            if t.uniform:
                body = f"{self.ctype(t.items[0])} v[{len(t.items)}];"
            else:  # element types first: their typedefs precede this one
                fields = t.names or tuple(f"f{k}" for k in range(len(t.items)))
                body = " ".join(f"{self.ctype(item)} {f};" for f, item in zip(fields, t.items))
            name = self._name(t.cname or f"T{len(self.structs)}")
        else:
            raise CodegenError(f"no C type for {t!r}")
        self.structs[t] = name
        self.struct_defs.append(f"typedef struct {{ {body} }} {name};")
        return name

    def obj_struct(self, cls: type) -> str:
        if cls not in self.structs:
            fields = dataclasses.fields(cls)
            self.structs[cls] = self._name(cls.__name__)
            self.struct_defs.append(f"typedef struct {{ {' '.join(f'double {f.name};' for f in fields)} }} "
                                    f"{self.structs[cls]};")
        return self.structs[cls]

    def constant(self, name: str, value: Any, where: str) -> tuple[str, Any]:
        if id(value) not in self.constants:
            t = _type_of_value(value, where)
            cname = f"g_{name}_{len(self.constants)}"
            self.constants[id(value)] = (cname, t)
            self.const_defs.append(f"static const {self.ctype(t)} {cname} = {_initializer(value, t)};")
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


def _initializer(value: Any, t: Any) -> str:
    if t == D:
        return _float(value)
    if t in (I, B):
        return str(int(value))
    if t == S:
        return _cstring(value)
    inner = ", ".join(_initializer(v, it) for v, it in zip(value, t.items))
    return f"{{{{{inner}}}}}" if t.uniform else f"{{{inner}}}"


def _float(v: float) -> str:
    if math.isnan(v):
        return "NAN"
    if math.isinf(v):
        return "INFINITY" if v > 0 else "(-INFINITY)"
    text = repr(float(v))  # shortest round-trip form: C's strtod reads back the same double
    return text if any(c in text for c in ".e") else text + ".0"


def _scalar_code(value: Any) -> Optional[tuple[str, Any]]:
    """A None, bool, int, float or str value as C code and type (None for other values)."""
    if value is None:
        return "", NONE
    if isinstance(value, bool):
        return ("1" if value else "0"), B
    if isinstance(value, int):
        return str(value), I
    if isinstance(value, float):
        return _float(value), D
    if isinstance(value, str):
        return _cstring(value), S
    return None


def _cstring(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _int_of(code: str) -> Optional[int]:
    """The value of an integer constant expression's code, or None."""
    try:
        return int(code.replace("(", "").replace(")", ""))
    except ValueError:
        return None


_SIMPLE = re.compile(r"^[A-Za-z_][\w.\[\]]*(->[\w.\[\]]+)?$")


def _terminates(stmts: list) -> bool:
    if not stmts:
        return False
    last = stmts[-1]
    if isinstance(last, (ast.Return, ast.Raise, ast.Break, ast.Continue)):
        return True
    if isinstance(last, ast.If):
        return _terminates(last.body) and _terminates(last.orelse)
    return False


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
        self.scope: dict[str, Any] = {}
        self.cvars: dict[tuple[str, Any], str] = {}
        self.aliases: dict[str, tuple[str, Any]] = {}
        self.temps: list[tuple[str, Any]] = []
        self.returns: list[tuple[str, Any]] = []
        self.loops: list[bool] = []  #: the enclosing Python loops, innermost last: True for a C loop
        params = [a.arg for a in node.args.args]
        if node.args.vararg or node.args.kwarg or node.args.kwonlyargs or len(args) != len(params):
            raise CodegenError(f"{self.where(node)}: {func.__name__}: only positional parameters "
                               f"(no *args, **kwargs, keyword-only), {len(params)} of them (got {len(args)} types)")
        pnames = []
        for pname, t in zip(params, args):
            if t == NONE:
                self.scope[pname] = NONE
                continue
            pnames.append((self.var(pname, t), t))
            self.scope[pname] = t
        body: list[str] = []
        self.block(node.body, body, 1)
        if not _terminates(node.body):
            self.returns.append(("", NONE))
            body.append(f"    return @R{len(self.returns) - 1}@;")
        self.ret = self.return_type(node)
        ret_c = unit.ctype(self.ret)
        text = "\n".join(body)
        for k, (code, t) in enumerate(self.returns):
            text = text.replace(f"@R{k}@", self.convert(code, t, self.ret))
        text = text.replace("@ZERO@", "0.0" if self.ret == D else "0" if self.ret in (I, B) else f"(({ret_c}){{0}})")
        signature = ", ".join(["int *err"] + [f"{unit.ctype(t)} {c}" for c, t in pnames])
        self.prototype = f"KERNEL {ret_c} {name}({signature})"
        param_vars = {c for c, _ in pnames}
        decls = [f"    {unit.ctype(t)} {c};" for (_, t), c in self.cvars.items() if c not in param_vars]
        decls += [f"    {unit.ctype(t)} {n};" for n, t in self.temps]
        self.code = (f"/* {func.__qualname__} ({shown_file(self.file)}:{node.lineno}) */\n"
                     f"{self.prototype}\n{{\n" + "\n".join(decls) + ("\n" if decls else "") + text + "\n}\n")

    # --- helpers ------------------------------------------------------------------------------
    def where(self, node: ast.AST) -> str:
        return f"{self.file}:{getattr(node, 'lineno', '?')}"

    def fail(self, node: ast.AST, what: str) -> CodegenError:
        return CodegenError(f"{self.where(node)}: in {self.func.__name__}: {what}")

    def return_type(self, node: ast.AST) -> Any:
        ret = None
        for _, t in self.returns:
            u = t if ret is None else _unify(ret, t)
            if u is None:
                raise self.fail(node, f"{self.func.__name__} returns values of different types")
            ret = u
        if ret is None or ret == NONE:
            raise self.fail(node, f"{self.func.__name__} returns nothing")
        return ret

    def convert(self, code: str, t: Any, to: Any) -> str:
        """``code`` of type ``t`` as a value of type ``to`` (see :func:`_unify`)."""
        if t == to:
            return code
        if to == D and t == I:
            return f"((double)({code}))"
        c = self.unit.ctype(to)
        if isinstance(to, Opt) and t == NONE:
            return f"(({c}){{0}})"
        if isinstance(to, Opt) and t == to.inner:
            return f"(({c}){{1, {code}}})"
        raise CodegenError(f"cannot convert {t} to {to}")

    def var(self, name: str, t: Any) -> str:
        key = (name, t)
        if key not in self.cvars:
            taken = sum(1 for n, _ in self.cvars if n == name)
            self.cvars[key] = f"v_{name}" if not taken else f"v_{name}_{taken}"
        return self.cvars[key]

    def temp(self, t: Any, code: str, out: list[str], indent: int) -> str:
        name = f"t{len(self.temps)}"
        self.temps.append((name, t))
        out.append("    " * indent + f"{name} = {code};")
        return name

    def simple(self, code: str, t: Any, out: list[str], ind: int) -> str:
        """``code`` as something that can be indexed repeatedly (a name or a temporary)."""
        return code if _SIMPLE.match(code) else self.temp(t, code, out, ind)

    def unwrap(self, code: str, t: Any) -> tuple[str, Any]:
        """An Optional used as a value: the program's own tests keep it from being None here."""
        return (f"{code}.v", t.inner) if isinstance(t, Opt) else (code, t)

    def value(self, e: ast.expr, out: list[str], ind: int) -> tuple[str, Any]:
        return self.unwrap(*self.expr(e, out, ind))

    def bind(self, node: ast.AST, name: str, t: Any) -> Optional[str]:
        """The C variable of ``name`` now holding type ``t`` (None: nothing to store)."""
        if name in self.aliases:
            raise self.fail(node, f"'{name}' is a loop constant or function here and cannot be assigned")
        self.scope[name] = t
        if t == NONE or (isinstance(t, Tup) and not t.items):
            return None
        return self.var(name, t)

    def store(self, node: ast.AST, name: str, code: str, t: Any, out: list[str], ind: int) -> None:
        if name == "_":
            return
        if isinstance(t, Fn):
            self.scope.pop(name, None)
            self.aliases[name] = (t.name, t)
            return
        target = self.bind(node, name, t)
        if target is not None:
            out.append(f"{'    ' * ind}{target} = {code};")

    # --- statements ---------------------------------------------------------------------------
    def block(self, stmts: list, out: list[str], indent: int) -> None:
        for s in stmts:
            self.stmt(s, out, indent)

    def source_note(self, s: ast.stmt, out: list[str], ind: int, suffix: str = "") -> None:
        """A comment with the Python line a statement comes from, for the reader of the C."""
        text = ast.unparse(s).splitlines()[0] if not isinstance(s, (ast.For, ast.If)) else \
            f"{'for' if isinstance(s, ast.For) else 'if'} {ast.unparse(s.target) + ' in ' + ast.unparse(s.iter) if isinstance(s, ast.For) else ast.unparse(s.test)}:"
        text = text if len(text) <= 90 else text[:87] + "..."
        out.append(f"{'    ' * ind}/* {s.lineno}: {text.replace('*/', '* /')}{suffix} */")

    def stmt(self, s: ast.stmt, out: list[str], ind: int) -> None:
        pad = "    " * ind
        if not (isinstance(s, ast.Expr) and isinstance(s.value, ast.Constant)) and not isinstance(s, ast.For):
            self.source_note(s, out, ind)
        if isinstance(s, ast.Expr):
            if isinstance(s.value, ast.Constant):
                return  # docstring
            if self.append(s.value, out, ind):
                return
            code, _ = self.expr(s.value, out, ind)
            out.append(f"{pad}(void)({code});")
        elif isinstance(s, (ast.Assign, ast.AnnAssign)):
            targets = s.targets if isinstance(s, ast.Assign) else [s.target]
            if s.value is None:
                raise self.fail(s, "a declaration without a value is not supported")
            if len(targets) == 1:
                self.assign(targets[0], s.value, out, ind)
            else:  # a = b = value: one evaluation
                code, t = self.expr(s.value, out, ind)
                if not all(isinstance(t_, ast.Name) for t_ in targets):
                    raise self.fail(s, "chained assignment only to names")
                code = self.simple(code, t, out, ind) if t not in (NONE,) else code
                for target in targets:
                    self.store(target, target.id, code, t, out, ind)
        elif isinstance(s, ast.AugAssign):
            if not isinstance(s.target, ast.Name):
                raise self.fail(s, "augmented assignment only to a name")
            load = ast.copy_location(ast.Name(s.target.id, ast.Load()), s)
            self.assign(s.target, ast.copy_location(ast.BinOp(load, s.op, s.value), s), out, ind)
        elif isinstance(s, ast.Return):
            if s.value is None:
                code, t = "", NONE
            else:
                code, t = self.expr(s.value, out, ind)
            if isinstance(t, (Fn, Poison)):
                raise self.fail(s, "this value cannot be returned")
            self.returns.append((code, t))
            out.append(f"{pad}return @R{len(self.returns) - 1}@;")
        elif isinstance(s, ast.If):
            self.if_stmt(s, out, ind)
        elif isinstance(s, ast.Raise):
            out.append(f"{pad}if (!*err) *err = {s.lineno};  /* {ast.unparse(s)[:60]} */")
            out.append(f"{pad}return @ZERO@;")
        elif isinstance(s, ast.For):
            self.for_stmt(s, out, ind)
        elif isinstance(s, ast.While):
            if s.orelse:
                raise self.fail(s, "while ... else is not supported")
            self.c_loop(s, None, out, ind)
        elif isinstance(s, (ast.Break, ast.Continue)):
            if not self.loops or not self.loops[-1]:
                raise self.fail(s, f"'{type(s).__name__.lower()}' only in a while loop or a range() loop with "
                                   f"bounds known at run time (this loop is unrolled)")
            out.append(f"{pad}{type(s).__name__.lower()};")
        elif isinstance(s, ast.Pass):
            pass
        else:
            raise self.fail(s, f"statement '{type(s).__name__}' is not supported")

    def append(self, e: ast.expr, out: list[str], ind: int) -> bool:
        """``name.append(x)`` on a list: the name now holds one element more."""
        if not (isinstance(e, ast.Call) and isinstance(e.func, ast.Attribute) and e.func.attr == "append"
                and isinstance(e.func.value, ast.Name) and e.func.value.id in self.scope):
            return False
        if len(e.args) != 1 or e.keywords:
            raise self.fail(e, "append() takes one argument")
        name = e.func.value
        item = ast.copy_location(ast.Tuple([e.args[0]], ast.Load()), e)
        self.assign(name, ast.copy_location(ast.BinOp(name, ast.Add(), item), e), out, ind)
        return True

    def if_stmt(self, s: ast.If, out: list[str], ind: int) -> None:
        pad = "    " * ind
        code, _ = self.expr(s.test, out, ind)
        before = dict(self.scope)
        body: list[str] = []
        self.block(s.body, body, ind + 1)
        after_body, self.scope = self.scope, dict(before)
        orelse: list[str] = []
        self.block(s.orelse, orelse, ind + 1)
        after_else = self.scope
        dead_body, dead_else = _terminates(s.body), _terminates(s.orelse)
        if dead_body or dead_else:
            self.scope = after_else if dead_body else after_body
        else:
            merged = {}
            for name in list(after_body) + [n for n in after_else if n not in after_body]:
                a, b = after_body.get(name), after_else.get(name)
                if a is None or b is None or a == b:
                    merged[name] = a if a is not None else b
                    continue
                u = _unify(a, b)
                if u is None:
                    merged[name] = Poison((a, b))
                    continue
                merged[name] = u
                for t, lines in ((a, body), (b, orelse)):
                    if t != u:
                        src = "" if t == NONE else self.var(name, t)
                        lines.append(f"{pad}    {self.var(name, u)} = {self.convert(src, t, u)};")
            self.scope = merged
        out.append(f"{pad}if ({code}) {{")
        out.extend(body)
        if orelse:
            out.append(f"{pad}}} else {{")
            out.extend(orelse)
        out.append(f"{pad}}}")

    def for_stmt(self, s: ast.For, out: list[str], ind: int) -> None:
        if s.orelse:
            raise self.fail(s, "for ... else is not supported")
        it = s.iter
        if isinstance(it, ast.Call) and isinstance(it.func, ast.Name) and it.func.id == "range":
            if not isinstance(s.target, ast.Name) or not 1 <= len(it.args) <= 3:
                raise self.fail(s, "'for name in range(...)' with one to three bounds")
            bounds = []
            for a in it.args:
                code, t = self.expr(a, out, ind)
                if t != I:
                    raise self.fail(s, "range() bounds must be integers")
                bounds.append(code)
            start, stop, step = (["0"] + bounds + ["1"])[-3:] if len(bounds) == 1 else (bounds + ["1"])[:3]
            values = [_int_of(b) for b in (start, stop, step)]
            if None not in values and values[2] != 0 and len(range(*values)) <= _UNROLL_MAX:
                name = s.target.id
                self.loops.append(False)
                for k in range(*values):
                    self.aliases[name] = (str(k), I)
                    self.source_note(s, out, ind, f" ({name} = {k}, unrolled)")
                    self.block(s.body, out, ind)
                self.loops.pop()
                self.aliases.pop(name, None)
                return
            self.source_note(s, out, ind)
            self.c_loop(s, (start, stop, step), out, ind)
            return
        self.loops.append(False)
        for k, row in enumerate(self.passes(s.target, it, out, ind, s)):
            self.source_note(s, out, ind, f" (element {k}, unrolled)")
            for target, code, t in row:
                self.assign_target(target, code, t, out, ind)
            self.block(s.body, out, ind)
        self.loops.pop()

    def passes(self, target: ast.expr, it: ast.expr, out: list[str], ind: int,
               node: ast.AST) -> list[list[tuple[ast.expr, str, Any]]]:
        """The passes of a loop over ``it`` unrolled (a constant range, ``zip`` of sequences, a
        sequence): per pass, the (target, code, type) each target takes."""
        if isinstance(it, ast.Call) and isinstance(it.func, ast.Name) and it.func.id == "range":
            bounds = [_int_of(self.expr(a, out, ind)[0]) for a in it.args]
            if None in bounds or not 1 <= len(bounds) <= 3:
                raise self.fail(node, "range() needs constant bounds here")
            return [[(target, str(k), I)] for k in range(*bounds)]
        if isinstance(it, ast.Call) and isinstance(it.func, ast.Name) and it.func.id == "zip":
            seqs = [self.sequence(a, out, ind) for a in it.args]
            if not isinstance(target, ast.Tuple) or len(target.elts) != len(seqs):
                raise self.fail(node, f"zip() of {len(seqs)} sequences needs {len(seqs)} targets")
            n = min(len(t.items) for _, t in seqs)
            return [[(sub, _element(c, t, k), t.items[k]) for sub, (c, t) in zip(target.elts, seqs)]
                    for k in range(n)]
        code, t = self.sequence(it, out, ind)
        return [[(target, _element(code, t, k), t.items[k])] for k in range(len(t.items))]

    def c_loop(self, s: ast.stmt, bounds: Optional[tuple[str, str, str]], out: list[str], ind: int) -> None:
        """A C loop: ``for`` over a range with ``bounds`` (start, stop, step), else a ``while``
        (its test evaluated at the top of every pass, with whatever it needs)."""
        pad = "    " * ind
        before = dict(self.scope)
        if bounds is not None:
            v = self.bind(s, s.target.id, I)
            out.append(f"{pad}for ({v} = {bounds[0]}; {v} < {bounds[1]}; {v} += {bounds[2]}) {{")
        else:
            out.append(f"{pad}for (;;) {{")
            code, _ = self.expr(s.test, out, ind + 1)
            out.append(f"{pad}    if (!{code}) break;")
        self.loops.append(True)
        self.block(s.body, out, ind + 1)
        self.loops.pop()
        out.append(f"{pad}}}")
        for n, t in before.items():
            if self.scope.get(n) != t:
                raise self.fail(s, f"'{n}' changes type inside the loop")

    def sequence(self, e: ast.expr, out: list[str], ind: int) -> tuple[str, Tup]:
        code, t = self.value(e, out, ind)
        if not isinstance(t, Tup):
            raise self.fail(e, "only fixed-length tuples and lists can be iterated")
        return (self.simple(code, t, out, ind) if t.items else code), t

    def assign_target(self, target: ast.expr, code: str, t: Any, out: list[str], ind: int) -> None:
        if isinstance(target, ast.Name):
            self.store(target, target.id, code, t, out, ind)
        elif isinstance(target, (ast.Tuple, ast.List)):
            code, t = self.unwrap(code, t)
            if not isinstance(t, Tup) or len(t.items) != len(target.elts):
                raise self.fail(target, f"cannot unpack {len(target.elts)} values here")
            if not _SIMPLE.match(code):
                code = self.temp(t, code, out, ind)
            for k, sub in enumerate(target.elts):
                self.assign_target(sub, _element(code, t, k), t.items[k], out, ind)
        else:
            raise self.fail(target, "only names and tuples of names can be assigned")

    def assign(self, target: ast.expr, value: ast.expr, out: list[str], ind: int) -> None:
        if isinstance(target, (ast.Tuple, ast.List)) and isinstance(value, (ast.Tuple, ast.List)):
            if len(value.elts) != len(target.elts):
                raise self.fail(target, "unpacking: lengths differ")
            parts = [self.expr(v, out, ind) for v in value.elts]  # all evaluated before any store
            held = []
            for c, t in parts:
                keep = isinstance(t, Fn) or t == NONE or (isinstance(t, Tup) and not t.items) or _int_of(c) is not None
                held.append((c if keep else self.temp(t, c, out, ind), t))
            for sub, (c, t) in zip(target.elts, held):
                self.assign_target(sub, c, t, out, ind)
            return
        code, t = self.expr(value, out, ind)
        self.assign_target(target, code, t, out, ind)

    # --- expressions --------------------------------------------------------------------------
    def expr(self, e: ast.expr, out: list[str], ind: int) -> tuple[str, Any]:
        if isinstance(e, ast.Constant):
            scalar = _scalar_code(e.value)
            if scalar is None:
                raise self.fail(e, f"constant {e.value!r} is not supported")
            return scalar
        if isinstance(e, ast.Name):
            return self.name(e)
        if isinstance(e, ast.Attribute):
            return self.attribute(e, out, ind)
        if isinstance(e, ast.BinOp):
            return self.binop(e, out, ind)
        if isinstance(e, ast.UnaryOp):
            if isinstance(e.op, ast.Not):
                code, _ = self.expr(e.operand, out, ind)
                return f"(!{code})", B
            code, t = self.value(e.operand, out, ind)
            if isinstance(e.op, (ast.USub, ast.UAdd)) and t in (D, I):
                k = _int_of(code) if t == I else None
                if k is not None:
                    return str(-k if isinstance(e.op, ast.USub) else k), I
                return f"({'-' if isinstance(e.op, ast.USub) else '+'}{code})", t
            raise self.fail(e, f"unary '{ast.unparse(e)}' is not supported")
        if isinstance(e, ast.Compare):
            return self.compare(e, out, ind)
        if isinstance(e, ast.BoolOp):
            op = " && " if isinstance(e.op, ast.And) else " || "
            return "(" + op.join(self.expr(v, out, ind)[0] for v in e.values) + ")", B
        if isinstance(e, ast.IfExp):
            test, _ = self.expr(e.test, out, ind)
            (a, ta), (b, tb) = self.expr(e.body, out, ind), self.expr(e.orelse, out, ind)
            u = _unify(ta, tb)
            if u is None or u == NONE:
                raise self.fail(e, "the branches of a conditional expression differ in type")
            return f"({test} ? {self.convert(a, ta, u)} : {self.convert(b, tb, u)})", u
        if isinstance(e, (ast.Tuple, ast.List)):
            return self.tuple_literal([self.value(v, out, ind) for v in e.elts])
        if isinstance(e, ast.ListComp):
            return self.tuple_literal(self.unrolled(e, out, ind))
        if isinstance(e, ast.Subscript):
            return self.subscript(e, out, ind)
        if isinstance(e, ast.Call):
            return self.call(e, out, ind)
        raise self.fail(e, f"expression '{ast.unparse(e)[:50]}' ({type(e).__name__}) is not supported")

    def tuple_literal(self, parts: list[tuple[str, Any]]) -> tuple[str, Any]:
        if not parts:
            return "", Tup(())
        if all(t in (D, I) for _, t in parts):  # a float sequence: its ints are floats
            parts = [(self.convert(c, t, D), D) for c, t in parts]
        t = Tup(tuple(pt for _, pt in parts))
        return self.literal(t, [c for c, _ in parts]), t

    def literal(self, t: Tup, codes: list[str]) -> str:
        inner = ", ".join(codes)
        return f"(({self.unit.ctype(t)}){{{{{inner}}}}})" if t.uniform else f"(({self.unit.ctype(t)}){{{inner}}})"

    def unrolled(self, e: ast.expr, out: list[str], ind: int) -> list[tuple[str, Any]]:
        """The elements of a comprehension over a fixed-length sequence or a constant range."""
        if len(e.generators) != 1 or e.generators[0].ifs or e.generators[0].is_async:
            raise self.fail(e, "only comprehensions with one 'for' and no 'if'")
        gen = e.generators[0]
        result = []
        saved = dict(self.aliases)
        for row in self.passes(gen.target, gen.iter, out, ind, e):
            for target, c, t in row:
                self.alias(target, c, t)
            result.append(self.value(e.elt, out, ind))
        self.aliases = saved
        return result

    def alias(self, target: ast.expr, code: str, t: Any) -> None:
        if isinstance(target, ast.Name):
            if target.id != "_":
                self.aliases[target.id] = (code, t)
        elif isinstance(target, (ast.Tuple, ast.List)):
            code, t = self.unwrap(code, t)
            if not isinstance(t, Tup) or len(t.items) != len(target.elts):
                raise self.fail(target, f"cannot unpack {len(target.elts)} values here")
            for k, sub in enumerate(target.elts):
                self.alias(sub, _element(code, t, k), t.items[k])
        else:
            raise self.fail(target, "only names and tuples of names as comprehension targets")

    def name(self, e: ast.Name) -> tuple[str, Any]:
        if e.id in self.aliases:
            return self.aliases[e.id]
        if e.id in self.scope:
            t = self.scope[e.id]
            if isinstance(t, Poison):
                raise self.fail(e, f"'{e.id}' has different types on the branches that reach here")
            if t == NONE:
                return "", NONE
            if isinstance(t, Tup) and not t.items:
                return "", t
            return self.var(e.id, t), t
        if e.id not in self.globals:
            raise self.fail(e, f"name '{e.id}' is not defined")
        value = self.globals[e.id]
        scalar = None if value is None or isinstance(value, str) else _scalar_code(value)
        if scalar is not None:
            return scalar
        if isinstance(value, tuple):
            return self.unit.constant(e.id.lstrip("_"), value, self.where(e))
        raise self.fail(e, f"global '{e.id}' ({type(value).__name__}) cannot be used as a value")

    def attribute(self, e: ast.Attribute, out: list[str], ind: int) -> tuple[str, Any]:
        if isinstance(e.value, ast.Name) and e.value.id not in self.scope and e.value.id not in self.aliases \
                and self.globals.get(e.value.id) is math:
            if e.attr in ("pi", "e", "tau", "inf", "nan"):
                return _float(getattr(math, e.attr)), D
            if e.attr in _MATH or e.attr in _MATH_BOOL:
                return e.attr, Fn(e.attr)
        if isinstance(e.value, ast.Name) and isinstance(self.scope.get(e.value.id), Obj):
            cls = self.scope[e.value.id].cls
            fields = {f.name for f in dataclasses.fields(cls)}
            if e.attr not in fields:
                raise self.fail(e, f"{cls.__name__} has no field '{e.attr}'")
            return f"{self.var(e.value.id, self.scope[e.value.id])}->{e.attr}", D
        if isinstance(e.value, (ast.Name, ast.Attribute, ast.Subscript)) and not (
                isinstance(e.value, ast.Name) and e.value.id not in self.scope and e.value.id not in self.aliases):
            code, t = self.value(e.value, out, ind)
            if isinstance(t, Tup) and t.names:
                if e.attr not in t.names:
                    raise self.fail(e, f"{t.cname} has no field '{e.attr}' (or it is not plain data)")
                k = t.names.index(e.attr)
                return _element(code, t, k), t.items[k]
        raise self.fail(e, f"attribute '{ast.unparse(e)}' is not supported (fields of parameters and "
                           f"math constants only)")

    def compare(self, e: ast.Compare, out: list[str], ind: int) -> tuple[str, Any]:
        if len(e.ops) != 1:
            raise self.fail(e, "only single comparisons (no chains) are supported")
        op = e.ops[0]
        if isinstance(op, (ast.Is, ast.IsNot)):
            if not (isinstance(e.comparators[0], ast.Constant) and e.comparators[0].value is None):
                raise self.fail(e, "'is' only as 'x is None' / 'x is not None'")
            code, t = self.expr(e.left, out, ind)
            test = "1" if t == NONE else f"(!{code}.some)" if isinstance(t, Opt) else "0"
            return (test if isinstance(op, ast.Is) else f"(!{test})"), B
        if type(op) not in _CMPOPS:
            raise self.fail(e, "only < <= > >= == != and 'is None' comparisons are supported")
        (a, ta), (b, tb) = self.value(e.left, out, ind), self.value(e.comparators[0], out, ind)
        if S in (ta, tb) and isinstance(op, (ast.Eq, ast.NotEq)) and ta == tb:
            return f"(strcmp({a}, {b}) {_CMPOPS[type(op)]} 0)", B
        if {ta, tb} - {D, I, B}:
            raise self.fail(e, "comparisons only between numbers (or == between strings)")
        return f"({a} {_CMPOPS[type(op)]} {b})", B

    def binop(self, e: ast.BinOp, out: list[str], ind: int) -> tuple[str, Any]:
        (a, ta), (b, tb) = self.value(e.left, out, ind), self.value(e.right, out, ind)
        if isinstance(e.op, ast.Add) and isinstance(ta, Tup) and isinstance(tb, Tup):
            if not ta.items or not tb.items:
                return (b, tb) if not ta.items else (a, ta)
            a = self.simple(a, ta, out, ind)
            b = self.simple(b, tb, out, ind)
            parts = [(_element(a, ta, k), ta.items[k]) for k in range(len(ta.items))] + \
                [(_element(b, tb, k), tb.items[k]) for k in range(len(tb.items))]
            t = Tup(tuple(pt for _, pt in parts))
            return self.literal(t, [c for c, _ in parts]), t
        if isinstance(e.op, ast.Mult) and {type(ta), type(tb)} == {Tup, Scalar}:
            (seq, st), (n, nt) = ((a, ta), (b, tb)) if isinstance(ta, Tup) else ((b, tb), (a, ta))
            count = _int_of(n) if nt == I else None
            if count is None:
                raise self.fail(e, "a sequence can be repeated only a constant number of times")
            if not st.items or count <= 0:
                return "", Tup(())
            seq = self.simple(seq, st, out, ind)
            parts = [(_element(seq, st, k), st.items[k]) for k in range(len(st.items))] * count
            t = Tup(tuple(pt for _, pt in parts))
            return self.literal(t, [c for c, _ in parts]), t
        if isinstance(e.op, ast.Pow) and not {ta, tb} - {D, I} and D in (ta, tb):
            # Python's float ** number is C's pow on doubles (float_pow): the same value
            return f"py_math2(err, {e.lineno}, pow, {a}, (double)({b}))", D
        if type(e.op) in _INTOPS and {ta, tb} <= {I, B}:
            return f"({a} {_INTOPS[type(e.op)]} {b})", I
        if type(e.op) not in _BINOPS or {ta, tb} - {D, I}:
            raise self.fail(e, f"operation '{ast.unparse(e)[:50]}' is not supported (+ - * / on floats, + on "
                               f"tuples, | & on ints)")
        if ta == I and tb == I:
            if isinstance(e.op, ast.Div):
                return f"py_div(err, {e.lineno}, (double)({a}), (double)({b}))", D
            x, y = _int_of(a), _int_of(b)
            if x is not None and y is not None:
                return str({ast.Add: x + y, ast.Sub: x - y, ast.Mult: x * y}[type(e.op)]), I
            return f"({a} {_BINOPS[type(e.op)]} {b})", I
        if isinstance(e.op, ast.Div):
            return f"py_div(err, {e.lineno}, {a}, {b})", D
        return f"({a} {_BINOPS[type(e.op)]} {b})", D

    def subscript(self, e: ast.Subscript, out: list[str], ind: int) -> tuple[str, Any]:
        code, t = self.value(e.value, out, ind)
        if not isinstance(t, Tup):
            raise self.fail(e, "only tuples and lists can be indexed")
        n = len(t.items)
        if isinstance(e.slice, ast.Slice):
            bounds = []
            for b, default in ((e.slice.lower, 0), (e.slice.upper, n)):
                if b is None:
                    bounds.append(default)
                    continue
                k = _int_of(self.expr(b, out, ind)[0])
                if k is None:
                    raise self.fail(e, "slice bounds must be integer constants (the length is fixed)")
                bounds.append(max(0, min(n, k + n if k < 0 else k)))
            if e.slice.step is not None:
                raise self.fail(e, "slices with a step are not supported")
            if bounds[1] <= bounds[0]:
                return "", Tup(())
            src = self.simple(code, t, out, ind)
            sub = Tup(t.items[bounds[0]:bounds[1]])
            return self.literal(sub, [_element(src, t, k) for k in range(bounds[0], bounds[1])]), sub
        index, ti = self.value(e.slice, out, ind)
        if ti != I:
            raise self.fail(e, "an index must be an int")
        k = _int_of(index)
        if k is not None:
            if not -n <= k < n:
                raise self.fail(e, f"index {k} out of range for {n} elements")
            return _element(code, t, k % n), t.items[k % n]
        if not t.uniform:
            raise self.fail(e, "a variable index needs a sequence whose elements have one type")
        return f"{self.simple(code, t, out, ind)}.v[{index}]", t.items[0]

    def call(self, e: ast.Call, out: list[str], ind: int) -> tuple[str, Any]:
        f = e.func
        if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and f.value.id not in self.scope:
            module = self.globals.get(f.value.id)
            if module is math:
                return self.math_call(f.attr, e, out, ind)
            if getattr(module, "__name__", "") == "numpy" and f.attr in ("array", "asarray") and len(e.args) == 1:
                return self.value(e.args[0], out, ind)  # a fixed-length sequence is already an array
            if getattr(module, "__name__", "") == "bisect" and f.attr == "bisect_right" and len(e.args) in (2, 4) \
                    and not e.keywords:
                (a, ta), (x, tx) = self.value(e.args[0], out, ind), self.value(e.args[1], out, ind)
                if not (isinstance(ta, Tup) and ta.homogeneous and tx in (D, I)):
                    raise self.fail(e, "bisect_right(a, x[, lo, hi]) on a float sequence")
                n = len(ta.items)
                bounds = [self.value(b, out, ind) for b in e.args[2:]]
                if any(tb != I for _, tb in bounds):
                    raise self.fail(e, "bisect_right's lo and hi must be ints")
                # kept within the sequence, where Python raises (lo < 0) or may index past its end
                lo, hi = (f"py_maxi({bounds[0][0]}, 0)", f"py_mini({bounds[1][0]}, {n})") if bounds else ("0", str(n))
                return f"py_bisect_right({self.simple(a, ta, out, ind)}.v, {lo}, {hi}, {x})", I
        if isinstance(f, ast.Name) and f.id in self.aliases and isinstance(self.aliases[f.id][1], Fn):
            return self.math_call(self.aliases[f.id][1].name, e, out, ind)
        if not isinstance(f, ast.Name) or f.id in self.scope or f.id in self.aliases:
            raise self.fail(e, f"call '{ast.unparse(f)}' is not supported")
        if f.id in ("any", "all", "sum") and len(e.args) == 1 and not e.keywords:
            arg = e.args[0]
            if isinstance(arg, (ast.GeneratorExp, ast.ListComp)):
                parts = self.unrolled(arg, out, ind)
            else:
                code, t = self.sequence(arg, out, ind)
                parts = [(_element(code, t, k), t.items[k]) for k in range(len(t.items))]
            if f.id == "sum":
                return self.sum(parts, e)
            if not parts:
                return ("1" if f.id == "all" else "0"), B
            return "(" + (" || " if f.id == "any" else " && ").join(c for c, _ in parts) + ")", B
        if f.id in ("min", "max"):
            if len(e.args) < 2 or e.keywords:
                raise self.fail(e, f"{f.id}() of two or more numbers")
            parts = [self.value(a, out, ind) for a in e.args]
            if any(t not in (D, I) for _, t in parts):
                raise self.fail(e, f"{f.id}() of numbers")
            kind = "" if any(t == D for _, t in parts) else "i"
            code = parts[0][0]
            for c, _ in parts[1:]:
                code = f"py_{f.id}{kind}({code}, {c})"
            return code, (D if kind == "" else I)
        if f.id in ("float", "abs", "tuple", "list", "len") or f.id in self.unit.identities:
            if len(e.args) != 1 or e.keywords:
                raise self.fail(e, f"{f.id}() takes one argument here")
            code, t = self.value(e.args[0], out, ind)
            if f.id == "float":
                if t not in (D, I):
                    raise self.fail(e, "float() of a number")
                return (code, D) if t == D else (f"((double)({code}))", D)
            if f.id == "abs":
                if t not in (D, I):
                    raise self.fail(e, "abs() of a number")
                return (f"fabs({code})", D) if t == D else (f"abs({code})", I)
            if f.id == "len":
                if not isinstance(t, Tup):
                    raise self.fail(e, "len() of a sequence")
                return str(len(t.items)), I
            if f.id in ("tuple", "list") and not isinstance(t, Tup):
                raise self.fail(e, f"{f.id}() of a fixed-length sequence")
            if isinstance(t, Tup) and t.names and f.id in ("tuple", "list"):
                t2 = Tup(t.items)
                return self.literal(t2, [_element(self.simple(code, t, out, ind), t, k) for k in range(len(t.items))]), t2
            return code, t
        target = self.globals.get(f.id)
        if isinstance(target, type) and issubclass(target, tuple) and hasattr(target, "_fields"):
            return self.construct(target, e, out, ind)
        if not isinstance(target, types.FunctionType):
            raise self.fail(e, f"call to '{f.id}' is not supported (kernels, NamedTuples, math.*, builtins)")
        sig = inspect.signature(target)
        try:
            bound = sig.bind(*e.args, **{k.arg: k.value for k in e.keywords})
        except TypeError as exc:
            raise self.fail(e, f"{f.id}(): {exc}") from None
        codes, arg_types = [], []
        for pname, param in sig.parameters.items():
            if pname in bound.arguments:
                code, t = self.expr(bound.arguments[pname], out, ind)
                if isinstance(t, (Fn, Poison)):
                    raise self.fail(e, f"{f.id}(): argument '{pname}' cannot be passed")
            elif param.default is not inspect.Parameter.empty:
                code, t = self.default(f"{target.__name__}_{pname}", param.default, e)
            else:
                raise self.fail(e, f"{f.id}(): parameter '{pname}' has no value")
            if t != NONE:
                codes.append(code)
            arg_types.append(t)
        name, ret = self.unit.specialize(target, tuple(arg_types), self.where(e))
        return f"{name}({', '.join(['err'] + codes)})", ret

    def sum(self, parts: list[tuple[str, Any]], e: ast.AST) -> tuple[str, Any]:
        """Python's sum() from its start 0: left to right; of floats from Python 3.12 on with
        Neumaier's compensation (as CPython's sum does)."""
        if any(t not in (D, I) for _, t in parts):
            raise self.fail(e, "sum() of numbers")
        if not any(t == D for _, t in parts):
            return "(" + " + ".join(["0"] + [c for c, _ in parts]) + ")", I
        if sys.version_info >= (3, 12):
            if any(t != D for _, t in parts):
                raise self.fail(e, "sum() of floats and ints mixed is not supported")
            return f"py_sum_compensated((const double[]){{{', '.join(c for c, _ in parts)}}}, {len(parts)})", D
        code = "0.0"
        for c, _ in parts:
            code = f"({code} + {c})"
        return code, D

    def default(self, name: str, value: Any, e: ast.AST) -> tuple[str, Any]:
        scalar = _scalar_code(value)
        if scalar is not None:
            return scalar
        if isinstance(value, tuple):
            return self.unit.constant(name.lstrip("_"), value, self.where(e))
        raise self.fail(e, f"default value {value!r} of '{name}' is not supported")

    def math_call(self, fname: str, e: ast.Call, out: list[str], ind: int) -> tuple[str, Any]:
        nargs = 1 if fname in _MATH_BOOL else _MATH.get(fname)
        if fname == "hypot":
            raise self.fail(e, "math.hypot is CPython's own algorithm, not C's hypot (the last bit may differ): "
                               "write math.sqrt(x * x + y * y), or keep this function Python")
        if nargs != len(e.args) or e.keywords:
            raise self.fail(e, f"math.{fname} with {len(e.args)} arguments is not supported")
        args = [self.value(a, out, ind) for a in e.args]
        if any(t not in (D, I) for _, t in args):
            raise self.fail(e, f"math.{fname} takes floats")
        values = ", ".join(c if t == D else f"(double)({c})" for c, t in args)
        if fname in _MATH_BOOL:
            return f"({fname}({values}) != 0)", B
        if fname == "fabs":  # never raises
            return f"fabs({values})", D
        if fname in ("sin", "cos"):  # raise for an infinite argument only: see py_trig
            return f"py_trig(err, {e.lineno}, {fname}, {values})", D
        return f"py_math{len(args)}(err, {e.lineno}, {fname}, {values})", D

    def construct(self, cls: type, e: ast.Call, out: list[str], ind: int) -> tuple[str, Any]:
        """A NamedTuple built from its fields: float, int and bool fields as annotated, Optional
        fields as their Optional type (so every return of a state has one C type), the others
        take their argument's type."""
        if e.keywords or len(e.args) != len(cls._fields):
            raise self.fail(e, f"{cls.__name__}(...) with all {len(cls._fields)} fields positional")
        hints = typing.get_type_hints(cls)
        codes, items = [], []
        for fname, arg in zip(cls._fields, e.args):
            want = {float: D, int: I, bool: B}.get(hints.get(fname))
            optional = typing.get_origin(hints.get(fname)) in (typing.Union, types.UnionType)
            if optional:
                want = _type_of_hint(hints[fname], self.where(e))
            code, t = self.expr(arg, out, ind) if optional else self.value(arg, out, ind)
            if want is not None and t != want:
                if want == D and t == I:
                    code = f"((double)({code}))"
                elif want == I and t == B:
                    pass
                elif isinstance(want, Opt) and (t == NONE or t == want.inner):
                    code = self.convert(code, t, want)
                else:
                    raise self.fail(e, f"{cls.__name__}.{fname} is {getattr(want, 'c', want)}, not {t}")
                t = want
            codes.append(code)
            items.append(t)
        t = Tup(tuple(items), tuple(cls._fields), cls.__name__, cls)
        return self.literal(t, codes), t


def shown_file(path: str) -> str:
    """A source file as the generated C names it: from ``deltafmi/`` for the package's own (a
    packaged model as ``deltafmi/models/...``, in a clone's ``fmu_src/`` too), else its name
    alone, so that the C (and the cache key made from it) does not depend on where the package
    or the component sits. A module generated into the build cache or the wheel's prebuilt layer
    (an equation model's, named after its content) is named alone too, wherever that cache is
    (inside a clone, a wheel's build folder or the user's home)."""
    from deltafmi.shipped import MODELS_DIR
    from deltafmi.toolchain import PREBUILT_DIR, cache_dir

    package = Path(__file__).resolve().parents[2]
    resolved = Path(path).resolve()
    if any(resolved.is_relative_to(folder.resolve()) for folder in (cache_dir(), PREBUILT_DIR)):
        return resolved.name
    for folder, shown in ((MODELS_DIR.resolve(), "deltafmi/models"), (package.parent, "")):
        try:
            relative = resolved.relative_to(folder).as_posix()
        except ValueError:
            continue
        return f"{shown}/{relative}" if shown else relative
    return resolved.name


def signature_of(func: Callable) -> list:
    """Argument types of ``func`` from its annotations: float -> D, a tuple of floats (or of such
    tuples) -> Tup, a dataclass of floats -> Obj, a NamedTuple -> its type. CodegenError for any
    other annotation (e.g. a list or a Sequence, whose length the C side must know)."""
    where = f"{inspect.getsourcefile(func)}:{func.__code__.co_firstlineno}"
    try:
        hints = typing.get_type_hints(func)
    except Exception as exc:  # noqa: BLE001 (unresolvable annotations: report them)
        raise CodegenError(f"{where}: {func.__name__}: annotations not resolvable ({exc})") from None

    def convert(name: str, hint: Any) -> Any:
        if dataclasses.is_dataclass(hint) and all(f.type in (float, "float") for f in dataclasses.fields(hint)):
            return Obj(hint)
        try:
            return _type_of_hint(hint, where)
        except CodegenError:
            what = "not annotated" if hint is None else repr(hint)
            raise CodegenError(f"{where}: {func.__name__}: parameter '{name}' is {what}; kernels take "
                               f"float, int, bool, fixed-length tuples, NamedTuples or a dataclass of floats") from None

    params = inspect.signature(func).parameters
    return [convert(name, hints.get(name)) for name in params]


def _element(code: str, t: Tup, k: int) -> str:
    if t.names:
        return f"{code}.{t.names[k]}"
    return f"{code}.v[{k}]" if t.uniform else f"{code}.f{k}"


HELPERS = """\
/* Where Python raises and C gives inf or nan (a division by zero; a math function outside its
 * domain or overflowing, by CPython's rule: nan from arguments that are not nan, inf from finite
 * ones) the line is recorded as a raise's: the entry returns it, and the FMU hands the call to
 * Python, which raises with its message. The value is C's, the same as Python's where it exists. */
static inline double py_div(int *err, int line, double a, double b)
{
    if (b == 0.0 && !*err) *err = line;
    return a / b;
}
static inline double py_math1(int *err, int line, double (*f)(double), double x)
{
    double r = f(x);
    if (!*err && ((isnan(r) && !isnan(x)) || (isinf(r) && isfinite(x)))) *err = line;
    return r;
}
/* sin and cos: Python raises for an infinite argument, nothing else. The check reads the argument
 * only and does not branch, so that the compiler computes sin and cos of one angle by one call of
 * libm's sincos (the same bits as sin and cos, at little more than the cost of one of them). */
static inline double py_trig(int *err, int line, double (*f)(double), double x)
{
    *err += (*err == 0) * (isinf(x) ? line : 0);
    return f(x);
}
static inline double py_math2(int *err, int line, double (*f)(double, double), double x, double y)
{
    double r = f(x, y);
    if (!*err && ((isnan(r) && !isnan(x) && !isnan(y)) || (isinf(r) && isfinite(x) && isfinite(y)))) *err = line;
    return r;
}
/* Python's min/max of two: the first argument on ties (and when the second is NaN) */
static inline double py_min(double a, double b) { return b < a ? b : a; }
static inline double py_max(double a, double b) { return b > a ? b : a; }
static inline int py_mini(int a, int b) { return b < a ? b : a; }
static inline int py_maxi(int a, int b) { return b > a ? b : a; }
/* sum() of n >= 1 floats from Python 3.12 on: 0 + x[0], then the rest with Neumaier's
 * compensation, which is added at the end when it is non-zero and finite */
static inline double py_sum_compensated(const double *x, int n)
{
    double s = 0.0 + x[0], lost = 0.0;
    for (int i = 1; i < n; i++) {
        double t = s + x[i];
        lost += fabs(s) >= fabs(x[i]) ? (s - t) + x[i] : (x[i] - t) + s;
        s = t;
    }
    return lost != 0.0 && isfinite(lost) ? s + lost : s;
}
/* bisect.bisect_right(a, x, lo, hi) */
static inline int py_bisect_right(const double *a, int lo, int hi, double x)
{
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (x < a[mid]) hi = mid; else lo = mid + 1;
    }
    return lo;
}
"""


def generate(entries: list[Entry], identities: Iterable[str] = (), returns: Optional[dict] = None,
             type_names: Optional[dict] = None) -> str:
    """One C translation unit with ``entries`` exported (see the module docstring).

    ``identities``: names of helper functions taken as the identity on their one argument (e.g.
    a list conversion that the fixed-length arrays make unnecessary). ``returns``, when given,
    receives each entry's result type by its C name. ``type_names``, when given, maps types
    (keys) to the C names of their values' types, filled in (an ``Obj``: its struct, not the
    pointer the kernels take).
    """
    unit = _Unit(identities)
    for t in type_names or ():
        type_names[t] = unit.obj_struct(t.cls) if isinstance(t, Obj) else unit.ctype(t)
    wrappers = []
    for entry in entries:
        where = f"{inspect.getsourcefile(entry.func)}:{entry.func.__code__.co_firstlineno}"
        name, ret = unit.specialize(entry.func, tuple(entry.args), where)
        if returns is not None:
            returns[entry.c_name] = ret
        params, call = ["int err = 0;"], []
        cparams = []
        for pname, t in zip(inspect.signature(entry.func).parameters, entry.args):
            if isinstance(t, Tup) and t.homogeneous:
                cparams.append(f"const double *{pname}")
                params.append(f"{unit.ctype(t)} a_{pname}; memcpy(a_{pname}.v, {pname}, sizeof a_{pname}.v);")
                call.append(f"a_{pname}")
            elif isinstance(t, Opt) and isinstance(t.inner, Tup) and t.inner.homogeneous:
                cparams.append(f"const double *{pname}")
                params.append(f"{unit.ctype(t)} a_{pname}; a_{pname}.some = {pname} != NULL; if ({pname}) "
                              f"memcpy(a_{pname}.v.v, {pname}, sizeof a_{pname}.v.v); else "
                              f"memset(&a_{pname}.v, 0, sizeof a_{pname}.v);")
                call.append(f"a_{pname}")
            elif isinstance(t, (Tup, Opt)):
                cparams.append(f"const {unit.ctype(t)} *{pname}")
                call.append(f"*{pname}")
            elif t == NONE:
                continue
            else:
                cparams.append(f"{unit.ctype(t)} {pname}")
                call.append(pname)
        if ret == D:
            cparams.append("double *out")
            store = "*out = result_;"
        elif isinstance(ret, Tup) and ret.homogeneous:
            cparams.append(f"double out[{len(ret.items)}]")
            store = "memcpy(out, result_.v, sizeof result_.v);"
        else:
            cparams.append(f"{unit.ctype(ret)} *out")
            store = "*out = result_;"
        wrappers.append(f"typedef {unit.ctype(ret)} {entry.c_name}_result;\n"
                        f"int {entry.c_name}({', '.join(cparams)})\n{{\n    "
                        + "\n    ".join(params)
                        + f"\n    {unit.ctype(ret)} result_ = {name}({', '.join(['&err'] + call)});\n    {store}\n"
                        f"    return err;\n}}\n")
    head = ("/* Generated by deltafmi.builder.codegen from the Python kernels named below; do not edit.\n"
            " * Compile with -ffp-contract=off -fno-builtin-pow (no fused multiply-add, pow(x, 2.0) not\n"
            " * folded to x * x): bit for bit with the Python. */\n"
            "#include <math.h>\n#include <stdlib.h>\n#include <string.h>\n\n"
            "/* Kernels are inlined into the entry: small structs then stay in registers (measured:\n"
            " * 0.89x the hand-written C's time, against 1.12x as plain static functions); a kernel\n"
            " * that would be copied into several callers at thousands of lines (KERNEL_SHARED) is\n"
            " * left to the compiler, which otherwise spends most of a build on the copies */\n"
            "#if defined(__GNUC__)\n#define KERNEL static inline __attribute__((always_inline))\n"
            "#else\n#define KERNEL static inline\n#endif\n#define KERNEL_SHARED static\n")
    prototypes, function_defs = _share_large_kernels(unit.prototypes, unit.function_defs, wrappers)
    return "\n".join([head, HELPERS, *unit.struct_defs, "", *unit.const_defs, "", *prototypes, "",
                      *function_defs, *wrappers])


#: a kernel called from more than one place is inlined only up to this many lines of C, counting
#: the kernels inlined into it
_INLINE_LINES = 2500


def _share_large_kernels(prototypes: list[str], function_defs: list[str],
                         wrappers: list[str]) -> tuple[list[str], list[str]]:
    """The prototypes and definitions with KERNEL_SHARED for each kernel that is called from more
    than one place and whose body, with the kernels inlined into it, exceeds _INLINE_LINES lines.
    Inlining changes no result (the kernels are compiled without floating-point contraction)."""
    names = [re.match(r"KERNEL .*? (k_\w+)\(", proto).group(1) for proto in prototypes]
    calls = [Counter(re.findall(r"\b(k_\w+)\(", code)) for code in function_defs]  # (each its own header too)
    sites = sum(calls, Counter(re.findall(r"\b(k_\w+)\(", "\n".join(wrappers)))) - Counter(names)
    lines: dict[str, int] = {}
    shared: set[str] = set()
    for name, code, called in zip(names, function_defs, calls):  # callees are defined before callers
        lines[name] = code.count("\n") + sum(count * lines[callee] for callee, count in called.items()
                                             if callee != name and callee in lines and callee not in shared)
        if sites[name] > 1 and lines[name] > _INLINE_LINES:
            shared.add(name)
    if not shared:
        return prototypes, function_defs

    def mark(text: str, name: str) -> str:
        return text.replace("KERNEL ", "KERNEL_SHARED ", 1) if name in shared else text
    return ([mark(proto, name) for proto, name in zip(prototypes, names)],
            [mark(code, name) for code, name in zip(function_defs, names)])
