"""Equation-based models: write equations, deltafmi compiles them (see docs/equations.md).

``from deltafmi.runtime.equations import EquationComponent, Model, Real, der, ...``: the
authoring side (standard library and numpy only, it runs inside the FMU too). The compiler is
``deltafmi.builder.equations`` (build time, sympy).
"""
from .component import EquationComponent
from .expr import (Equation, Expr, Vec, abs_, acos, asin, atan, atan2, cat, cos, cosh, der, edge, equations, exp,
                   ifelse, jacobian, log, pre, sin, sinh, sqrt, tan, tanh, time, vec, zeros)
from .model import (Connector, Discrete, EquationModelError, Flow, If, Model, Potential, Real, assign, connect,
                    flatten, reinit, when)

__all__ = ["Connector", "Discrete", "Equation", "EquationComponent", "EquationModelError", "Expr", "Flow", "If", "Model",
           "Potential", "Real", "Vec", "abs_", "acos", "asin", "assign", "atan", "atan2", "cat", "connect", "cos", "cosh",
           "der", "edge", "equations", "exp", "flatten", "ifelse", "jacobian", "log", "pre", "reinit", "sin", "sinh",
           "sqrt", "tan", "tanh", "time", "vec", "when", "zeros"]
