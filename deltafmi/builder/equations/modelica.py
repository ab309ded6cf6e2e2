"""``deltafmi build model.mo``: a flat subset of Modelica, parsed and flattened by rumoca (the
Rumoca compiler's Python package), written out as an equation model in deltafmi's Python form,
which the ordinary pipeline then compiles (the FMU carries that Python file as its model).

Taken: scalar ``parameter``/``constant`` Real, Integer and Boolean (bindings of literals and of
earlier parameters), ``input``/``output`` and other Real and discrete variables with start values,
equations of ``+ - * / ^``, relations, ``and or not``, if-expressions, ``der pre edge`` and the
usual math functions, ``initial equation``, ``when`` clauses with ``reinit`` and assignments.
Anything else (arrays, algorithms, for- and if-equations, user functions, elsewhen) is a build
error naming the construct.
"""
from __future__ import annotations

import hashlib
import keyword
import math
import re
from pathlib import Path
from typing import Any, Optional

from ..source_error import ComponentSourceError

__all__ = ["python_source_for"]

_BINARY = {"Add": "+", "Sub": "-", "Mul": "*", "Div": "/", "Exp": "**", "Lt": "<", "Le": "<=", "Gt": ">",
           "Ge": ">=", "And": "&", "Or": "|"}
_FUNCTIONS = {"Sin": "sin", "Cos": "cos", "Tan": "tan", "Asin": "asin", "Acos": "acos", "Atan": "atan",
              "Sinh": "sinh", "Cosh": "cosh", "Tanh": "tanh", "Exp": "exp", "Log": "log", "Sqrt": "sqrt",
              "Abs": "abs_", "Der": "der", "Pre": "pre", "Edge": "edge", "Atan2": "atan2"}


class ModelicaImportError(ComponentSourceError):
    """The Modelica file cannot be taken (not parsed, or outside the subset)."""


def python_source_for(path: Path, model: Optional[str], folder: Path) -> tuple[Path, str]:
    """(the Python equation model written for ``path``'s model ``model`` into ``folder``, its class)."""
    try:
        import rumoca
    except ImportError:
        raise ModelicaImportError(f"{path}: building a Modelica file needs rumoca (pip install rumoca)") from None
    text = Path(path).read_text()
    name = model or _only_model(text, path)
    try:
        flat = rumoca.Session().loads(text, model=name, filename=str(path)).to_dict("flat")
    except Exception as exc:  # noqa: BLE001 - rumoca's diagnostics, one line
        raise ModelicaImportError(f"{path}: {' '.join(str(exc).split())[:400]}") from None
    source = _Translator(flat, name, Path(path)).source()
    digest = hashlib.sha256(source.encode()).hexdigest()[:12]
    folder.mkdir(parents=True, exist_ok=True)
    out = folder / f"{_ident(Path(path).stem)}_{digest}.py"
    if not out.exists():
        out.write_text(source)
    return out, _ident(name)


def _only_model(text: str, path: Path) -> str:
    names = re.findall(r"^\s*(?:partial\s+)?model\s+([A-Za-z_]\w*)", text, flags=re.M)
    if len(names) != 1:
        raise ModelicaImportError(f"{path}: {'no model' if not names else 'several models'} in it; name one as "
                                  f"{path}:ModelName")
    return names[0]


def _ident(name: str) -> str:
    """A Python attribute for a Modelica name: not a keyword, nor a name the component base uses."""
    from deltafmi.runtime.equations import EquationComponent

    out = re.sub(r"\W", "_", name)
    out = out if not out[:1].isdigit() else "_" + out
    return out + "_" if keyword.iskeyword(out) or hasattr(EquationComponent, out) else out


def _line(node: Any) -> str:
    return ""


class _Translator:
    def __init__(self, flat: dict, name: str, path: Path) -> None:
        self.flat, self.name, self.path = flat, name, path
        self.attr: dict[str, str] = {}
        self.parameters: dict[str, float] = {}

    def fail(self, what: str) -> ModelicaImportError:
        return ModelicaImportError(f"{self.path}: {self.name}: {what} is outside the Modelica subset deltafmi "
                                   f"builds (docs/equations.md)")

    def source(self) -> str:
        lines = [f'"""{self.name}: translated from {self.path.name} (Modelica, through rumoca) by deltafmi."""',
                 "from deltafmi.component import Input, Output, Parameter",
                 "from deltafmi.runtime.equations import (Discrete, EquationComponent, Real, abs_, acos, asin, assign,",
                 "                                        atan, atan2, cos, cosh, der, edge, exp, ifelse, log, pre,",
                 "                                        reinit, sin, sinh, sqrt, tan, tanh, when)",
                 "from deltafmi.runtime.equations.expr import as_expr", "", "",
                 f"class {_ident(self.name)}(EquationComponent):",
                 f'    """Modelica model {self.name} ({self.path.name})."""', ""]
        types = self.flat.get("variable_type_names", {})
        for name, var in self.flat["variables"].items():
            if var.get("dims"):
                raise self.fail(f"the array {name}")
            attr = _ident(name)
            self.attr[name] = attr
            lines.append("    " + self.declaration(name, attr, var, types.get(name, "Real")))
        names = {"algorithms": "an algorithm section", "initial_algorithms": "an initial algorithm",
                 "structured_equations": "an array, for- or if-equation", "initial_structured_equations":
                 "an array, for- or if-equation in the initial equations"}
        for section, what in names.items():
            if self.flat.get(section):
                raise self.fail(what)
        body = [self.equation(e) for e in self.flat["equations"]]
        body += [self.when(w) for w in self.flat.get("when_chains", [])]
        lines += ["", "    def equations(self):", "        return [" + ",\n                ".join(body or []) + "]"]
        initial = [self.equation(e) for e in self.flat.get("initial_equations", [])]
        if initial:
            lines += ["", "    def initial_equations(self):",
                      "        return [" + ",\n                ".join(initial) + "]"]
        return "\n".join(lines) + "\n"

    def declaration(self, name: str, attr: str, var: dict, type_name: str) -> str:
        variability = var.get("variability")
        kind = next(iter(variability)) if isinstance(variability, dict) else variability
        causality = var.get("causality")
        causality = next(iter(causality)) if isinstance(causality, dict) else causality
        options = []
        if var.get("unit"):
            options.append(f"unit={self.literal_text(var['unit'])!r}")
        if var.get("description"):
            options.append(f"description={var['description']!r}")
        if attr != name:
            options.append(f"name={name!r}")
        python_type = {"Real": "float", "Integer": "int", "Boolean": "bool"}.get(type_name)
        if python_type is None:
            raise self.fail(f"the {type_name} variable {name}")
        extra = "" if python_type == "float" else f", type={python_type}"
        if kind in ("Parameter", "Constant"):
            value = self.evaluate(var.get("binding") or var.get("start"), name)
            self.parameters[name] = value
            return f"{attr} = Parameter({self.number(value, python_type)}{extra}{''.join(', ' + o for o in options)})"
        start = self.evaluate(var["start"], name) if var.get("start") else 0.0
        if causality == "Input":
            return f"{attr} = Input({self.number(start, python_type)}{extra}{''.join(', ' + o for o in options)})"
        if causality == "Output":
            return f"{attr} = Output({self.number(start, python_type)}{extra}{''.join(', ' + o for o in options)})"
        cls = "Discrete" if var.get("is_discrete_type") or kind == "Discrete" else "Real"
        options = [o for o in options if not o.startswith("description")]
        return f"{attr} = {cls}({float(start)!r}{''.join(', ' + o for o in options)})"

    @staticmethod
    def number(value: float, python_type: str) -> str:
        if python_type == "int":
            return repr(int(value))
        if python_type == "bool":
            return repr(bool(value))
        return repr(float(value))

    def literal_text(self, node: Any) -> str:
        if isinstance(node, str):
            return node
        value = node.get("Literal", {}).get("value", {})
        return value.get("String", "") if isinstance(value, dict) else str(value)

    def evaluate(self, node: Any, name: str) -> float:
        """A parameter's binding or a start value: literals and earlier parameters."""
        if node is None:
            return 0.0
        if "Literal" in node:
            value = node["Literal"]["value"]
            return float(next(iter(value.values())))
        if "VarRef" in node:
            ref = node["VarRef"]["name"]["name"]
            if ref not in self.parameters:
                raise self.fail(f"{name}'s value {ref} (not a parameter declared before it)")
            return self.parameters[ref]
        if "Unary" in node:
            value = self.evaluate(node["Unary"]["rhs"], name)
            return -value if node["Unary"]["op"] == "Minus" else value
        if "Binary" in node:
            op = node["Binary"]["op"]
            a, b = self.evaluate(node["Binary"]["lhs"], name), self.evaluate(node["Binary"]["rhs"], name)
            ops = {"Add": a + b, "Sub": a - b, "Mul": a * b}
            if op in ops:
                return ops[op]
            if op == "Div":
                return a / b
            if op == "Exp":
                return a ** b
        if "BuiltinCall" in node and node["BuiltinCall"]["function"] in _FUNCTIONS:
            f = getattr(math, _FUNCTIONS[node["BuiltinCall"]["function"]].rstrip("_"), None)
            if f is not None:
                return f(*[self.evaluate(a, name) for a in node["BuiltinCall"]["args"]])
        raise self.fail(f"the value of {name}")

    def equation(self, equation: dict) -> str:
        r = equation["residual"]
        if "Binary" in r and r["Binary"]["op"] == "Sub":
            return f"{self.expr(r['Binary']['lhs'])} == {self.expr(r['Binary']['rhs'])}"
        return f"0.0 == {self.expr(r)}"

    def when(self, chain: dict) -> str:
        if chain.get("else_when"):
            raise self.fail("elsewhen")
        first = chain["first"]
        body = []
        for item in first["equations"]:
            if "Reinit" in item:
                body.append(f"reinit(self.{self.attr[item['Reinit']['state']]}, {self.expr(item['Reinit']['value'])})")
            elif "Assign" in item:
                body.append(f"assign(self.{self.attr[item['Assign']['target']]}, {self.expr(item['Assign']['value'])})")
            else:
                raise self.fail(f"the when statement {next(iter(item))}")
        return f"when({self.expr(first['condition'])}, {', '.join(body)})"

    def expr(self, node: Any) -> str:
        if "Literal" in node:
            value = node["Literal"]["value"]
            kind, v = next(iter(value.items()))
            return repr(float(v)) if kind in ("Real", "Integer") else repr(bool(v)) if kind == "Boolean" else \
                self._bad(f"the literal {v!r}")
        if "VarRef" in node:
            ref = node["VarRef"]
            if ref.get("subscripts"):
                raise self.fail("a subscripted variable")
            return f"self.{self.attr[ref['name']['name']]}"
        if "Binary" in node:
            b = node["Binary"]
            a, c = self.expr(b["lhs"]), self.expr(b["rhs"])
            if b["op"] == "Eq":
                return f"as_expr({a}).is_({c})"
            if b["op"] == "Neq":
                return f"(~as_expr({a}).is_({c}))"
            if b["op"] not in _BINARY:
                raise self.fail(f"the operator {b['op']}")
            return f"({a} {_BINARY[b['op']]} {c})"
        if "Unary" in node:
            u = node["Unary"]
            inner = self.expr(u["rhs"])
            return {"Minus": f"(-{inner})", "Plus": inner, "Not": f"(~{inner})"}.get(u["op"]) or \
                self._bad(f"the operator {u['op']}")
        if "BuiltinCall" in node:
            call = node["BuiltinCall"]
            f = _FUNCTIONS.get(call["function"])
            if f is None:
                raise self.fail(f"the built-in {call['function']}")
            return f"{f}({', '.join(self.expr(a) for a in call['args'])})"
        if "If" in node:
            out = self.expr(node["If"]["else_branch"])
            for cond, value in reversed(node["If"]["branches"]):
                out = f"ifelse({self.expr(cond)}, {self.expr(value)}, {out})"
            return out
        raise self.fail(f"the expression {next(iter(node))}")

    def _bad(self, what: str) -> str:
        raise self.fail(what)
