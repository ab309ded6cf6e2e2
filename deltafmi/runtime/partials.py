"""``fmi2GetDirectionalDerivative`` for a component: exact where it gives them, numerical elsewhere.

FMI 2.0 (section 2.1.9) asks for ``dv_unknown = (d h / d v_known) dv_known``: the unknowns are
state derivatives and Real outputs, the knowns continuous states and Real inputs. A component may
return exact partial derivatives from :meth:`~deltafmi.runtime.Component.jacobian`; the rows it
leaves out are central differences along the seed direction, with a step of eps^(1/3) relative
to each known's scale ``max(|value|, nominal)`` (two evaluations per call, whatever the number of
knowns). The values of every variable are restored afterwards.
"""
from __future__ import annotations

from typing import Any, Optional

import numpy as np

from .base import Component
from .variables import flatten

__all__ = ["DirectionalDerivatives"]

#: relative central-difference step: balances truncation (step^2) against rounding (eps / step)
FD_STEP = float(np.finfo(float).eps) ** (1.0 / 3.0)
_MAX_PLANS = 1024
#: resolved (unknowns, knowns) pairs per component class, shared by its instances (an importer
#: that builds its Jacobian column by column asks the same nx + nu questions of every instance)
_PLANS: dict[tuple[type, bytes, bytes], "_Plan"] = {}


class _Plan:
    """One (unknowns, knowns) pair of value-reference lists, resolved once."""

    def __init__(self, owner: "DirectionalDerivatives", unknowns: np.ndarray, knowns: np.ndarray) -> None:
        columns = []
        for vr in knowns.tolist():
            column = owner.known_column.get(vr)
            if column is None:
                raise ValueError(f"fmi2GetDirectionalDerivative: {owner.describe(vr)} is not a known: FMI 2.0 "
                                 "allows the continuous states and the Real inputs")
            columns.append(column)
        rows: list[tuple[str, int]] = []
        for vr in unknowns.tolist():
            found = owner.unknown_row.get(vr)
            if found is None:
                raise ValueError(f"fmi2GetDirectionalDerivative: {owner.describe(vr)} is not an unknown: FMI 2.0 "
                                 "allows the state derivatives and the Real outputs")
            rows.append(found)
        self.columns = np.array(columns, dtype=np.intp)
        # the knowns' value references may repeat: numerical differences move each buffer once
        self.unique_columns, self.inverse = np.unique(self.columns, return_inverse=True)
        self.known_buffer = owner.column_buffer[self.unique_columns]
        self.known_nominal = owner.column_nominal[self.unique_columns]
        #: per unknown key ("der" or an output's name): (positions in the result, rows of its matrix)
        grouped: dict[str, tuple[list[int], list[int]]] = {}
        for position, (key, row) in enumerate(rows):
            positions, matrix_rows = grouped.setdefault(key, ([], []))
            positions.append(position)
            matrix_rows.append(row)
        self.groups = {k: (np.array(p, dtype=np.intp), np.array(r, dtype=np.intp)) for k, (p, r) in grouped.items()}
        #: per key: flat indices of the (rows x knowns) block in a C-ordered (rows, n_known) matrix
        self.blocks = {k: r[:, None] * owner.n_known + self.columns[None, :] for k, (_, r) in self.groups.items()}
        self.size = len(rows)
        #: one group whose rows come in result order: its flat indices, for a one-known shortcut
        only = next(iter(self.groups.values())) if len(self.groups) == 1 else None
        self.only = next(iter(self.groups)) if only is not None else ""
        self.whole = (next(iter(self.blocks.values()))[:, 0] if only is not None and len(columns) == 1
                      and np.array_equal(only[0], np.arange(len(rows))) else None)
        self.output_buffers = {k: owner.output_buffers[k][r] for k, (_, r) in self.groups.items() if k != "der"}


class DirectionalDerivatives:
    """The directional derivatives of one FMU instance's component (see the module docstring)."""

    def __init__(self, cls: type[Component]) -> None:
        layout = cls._layout
        nx = self.nx = layout.nx
        self.cls = cls
        inputs = [s for s in layout.scalars if s.causality == "input" and s.fmi_type == "Real"]
        self.known_column = {vr: vr for vr in range(nx)}
        self.known_column.update({s.value_reference: nx + k for k, s in enumerate(inputs)})
        self.column_buffer = np.array(list(range(nx)) + [s.value_reference for s in inputs], dtype=np.intp)
        self.column_nominal = np.array(list(layout.nominals) + [abs(s.nominal or 1.0) for s in inputs])
        self.n_known = nx + len(inputs)
        self.unknown_row: dict[int, tuple[str, int]] = {layout.dx_offset + i: ("der", i) for i in range(nx)}
        self.output_buffers: dict[str, np.ndarray] = {}
        for decl in layout.declarations:
            if decl.causality == "output" and decl.fmi_type == "Real":
                self.output_buffers[decl.name] = np.arange(decl.offset, decl.offset + decl.size)
                self.unknown_row.update({decl.offset + i: (decl.name, i) for i in range(decl.size)})
        self.names = {s.value_reference: s.name for s in layout.scalars}
        # what the exact Jacobian may depend on: states, parameters, inputs (and the int buffer),
        # as runs of consecutive reals (compared as bytes: no copies through fancy indexing)
        independent = [s.value_reference for s in layout.scalars[:layout.n_real]
                       if s.value_reference < nx or s.causality in ("parameter", "input")]
        self.runs: list[slice] = []
        for vr in independent:
            if self.runs and self.runs[-1].stop == vr:
                self.runs[-1] = slice(self.runs[-1].start, vr + 1)
            else:
                self.runs.append(slice(vr, vr + 1))
        self.exact = cls.provides_jacobian()
        #: the instance's compiled kernels (set by the instance): the differences evaluate them,
        #: and their jacobian kernel, when there is one, stands for the float part of ``jacobian()``
        self.native: Optional[Any] = None
        self._key: Optional[tuple] = None
        self._blocks: dict[str, np.ndarray] = {}
        self._checked: set[str] = set()

    def describe(self, vr: int) -> str:
        """``value reference 7 (der(x))`` or ``value reference 99 (no such variable)``."""
        return f"value reference {vr} ({self.names.get(vr, 'no such variable')})"

    def invalidate(self) -> None:
        """Forget the cached exact Jacobian (an event or a restored FMU state may change the model)."""
        self._key = None

    # --- the fmi2 call ------------------------------------------------------------------------
    def directional(self, comp: Component, t: float, unknowns: bytes, knowns: bytes, seed: bytes) -> bytes:
        """``dvUnknown`` (float64 bytes) for value references ``unknowns``/``knowns`` (uint32 bytes)
        and the seed ``dvKnown`` (float64 bytes)."""
        plan = _PLANS.get((self.cls, unknowns, knowns))
        if plan is None:
            if len(_PLANS) >= _MAX_PLANS:
                _PLANS.clear()
            plan = _PLANS[(self.cls, unknowns, knowns)] = _Plan(
                self, np.frombuffer(unknowns, dtype=np.uint32), np.frombuffer(knowns, dtype=np.uint32))
        direction = np.frombuffer(seed, dtype=float)
        blocks = self.blocks(comp, t) if self.exact else {}
        if plan.whole is not None:
            matrix = blocks.get(plan.only)
            if matrix is not None:  # the usual: one known, one kind of unknown, all exact
                return (np.take(matrix, plan.whole) * direction[0]).tobytes()
        result = np.zeros(plan.size)
        numeric = []
        for key, (positions, _) in plan.groups.items():
            matrix = blocks.get(key)
            if matrix is None:
                numeric.append(key)
            else:
                result[positions] = np.take(matrix, plan.blocks[key]) @ direction
        if numeric:
            self._differences(comp, t, plan, direction, numeric, result)
        return result.tobytes()

    def blocks(self, comp: Component, t: float) -> dict[str, np.ndarray]:
        """The component's exact Jacobian blocks, cached while time, variables and model stay."""
        real = comp._real
        key = (t, id(comp), comp._int.tobytes(), *(real[run].tobytes() for run in self.runs))
        if key != self._key:
            values = self.native.jacobian_values(t) if self.native is not None else None
            given = (self.cls.native.jacobian.then(values) if values is not None else comp.jacobian(t)) or {}
            self._blocks = {k: self._checked_block(k, np.ascontiguousarray(m, dtype=float)) for k, m in given.items()}
            self._key = key
        return self._blocks

    def state_jacobian(self, comp: Component, t: float) -> np.ndarray:
        """d der(x) / d x (nx x nx): exact when the component gives it, else by differences."""
        exact = self.blocks(comp, t).get("der") if self.exact else None
        if exact is not None:
            return exact[:, :self.nx]
        vrs = np.arange(self.nx, dtype=np.uint32)
        unknowns = (vrs + self.nx).tobytes()
        columns = [np.frombuffer(self.directional(comp, t, unknowns, vrs[j:j + 1].tobytes(),
                                                  np.ones(1).tobytes())) for j in range(self.nx)]
        return np.column_stack(columns)

    def _checked_block(self, key: str, matrix: np.ndarray) -> np.ndarray:
        if key not in self._checked:
            rows = self.nx if key == "der" else len(self.output_buffers.get(key, ()))
            if key != "der" and key not in self.output_buffers:
                raise ValueError(f"{self.cls.__name__}.jacobian(): '{key}' is neither 'der' nor a Real output; "
                                 f"the Real outputs are {', '.join(self.output_buffers) or 'none'}")
            if matrix.shape != (rows, self.n_known):
                raise ValueError(f"{self.cls.__name__}.jacobian()['{key}'] has shape {matrix.shape}; expected "
                                 f"({rows}, {self.n_known}): {'the state derivatives' if key == 'der' else key} "
                                 f"by the {self.nx} states and then the {self.n_known - self.nx} Real inputs")
            self._checked.add(key)
        return matrix

    def _differences(self, comp: Component, t: float, plan: _Plan, direction: np.ndarray, keys: list,
                     result: np.ndarray) -> None:
        """Central differences along ``direction`` for the unknowns of ``keys``, into ``result``."""
        step = np.bincount(plan.inverse, weights=direction, minlength=len(plan.unique_columns))
        moving = step != 0.0
        if not moving.any():
            return  # a zero seed: the derivative is zero
        x0 = comp._real[plan.known_buffer]
        scale = np.maximum(np.abs(x0), plan.known_nominal)
        h = FD_STEP * float(np.min(scale[moving] / np.abs(step[moving])))
        saved_real, saved_int = comp._real.copy(), comp._int.copy()
        try:
            comp._real[plan.known_buffer] = x0 + h * step
            plus = self._unknowns(comp, t, keys, plan)
            comp._real[plan.known_buffer] = x0 - h * step
            minus = self._unknowns(comp, t, keys, plan)
        finally:
            comp._real[:] = saved_real
            comp._int[:] = saved_int
        for key in keys:
            positions, _ = plan.groups[key]
            result[positions] = (plus[key] - minus[key]) / (2.0 * h)

    def _unknowns(self, comp: Component, t: float, keys: list, plan: _Plan) -> dict[str, Any]:
        values: dict[str, Any] = {}
        native = self.native
        if "der" in keys:
            if native is not None and native.derivatives(t):  # the compiled kernel: the same bits
                offset = self.cls._layout.dx_offset
                derivatives = comp._real[offset: offset + self.nx].copy()
            else:
                derivatives = flatten(comp.derivatives(t))
            values["der"] = derivatives[plan.groups["der"][1]]
        outputs = [k for k in keys if k != "der"]
        if outputs:
            if native is None or not native.outputs(t):
                comp.outputs(t)
            values.update({k: comp._real[plan.output_buffers[k]] for k in outputs})
        return values
