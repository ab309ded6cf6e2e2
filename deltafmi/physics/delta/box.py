"""The robot, a movable box and the table: the seed talk's "cartoon" with the delta robot.

One Lagrangian system of 12 coordinates, the robot's nine joint angles (its closed loops inside
its own dynamics, as in :mod:`.contact`) and a box of :class:`~deltafmi.physics.contact_problems.
box_on_table.BoxModel` (x, height above the table, rotation theta; planar in the vertical x-z plane,
long along y, frictionless), with six gaps:

    0  tool tip - table          h = tip_z - table                       (the tool missing the box)
    1  tool tip - box top face   h = n . (tip - c) - top,   n = (-sin theta, cos theta)
    2-5  box corners - table     (bottom-left, bottom-right, top-right, top-left), as BoxModel

``c`` is the box's centre of mass in the x-z plane and ``top`` the height of its top face above it
(the face is taken as a line: the tool is meant to press within it). The tool pushes the box along
``n`` and the box pushes back: row 1 of ``H`` has both parts, ``[n_x Jv_x + n_z Jv_z, -n_x, -n_z,
-t . (tip - c)]`` with ``t = (cos theta, sin theta)``. Every contact runs through the FREE /
COLLISION / CONTACT machine with its own material; a collision's effective mass comes from the
constrained response of both bodies (``contact_mobility``).
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from ..contact.material import CompliantMaterial
from ..contact.system import LagrangianModel
from deltafmi.physics.contact_problems.box_on_table import BoxModel
from .contact import DeltaToolModel, Plane, RobotContactSystem
from .contact_kernels import BoxTable, box_evaluation, box_outputs, contact_law
from .dynamics import accelerations, mass_matrix
from .kinematics import wrist_along
from .params import DeltaParams

__all__ = ["DeltaBoxModel", "BoxTableSystem", "make_robot_box_contact", "BOX_CONTACTS"]

#: names of the six contacts, in order
BOX_CONTACTS = ("tool-table", "tool-box", "corner 1-table", "corner 2-table", "corner 3-table",
                "corner 4-table")


class DeltaBoxModel(LagrangianModel):
    """The robot with a tool, a box and a horizontal table at ``table_height``.

    State ``q = [robot joint angles (9), box x, box height above the table, box theta]``. Inputs as
    attributes: ``u``, ``f`` (the robot's, as :class:`DeltaToolModel`) and ``box.force``.
    """

    n_q = 12
    n_c = 6

    def __init__(self, params: DeltaParams, table_height: float, box: BoxModel,
                 tool: Sequence[float] = (0.0, 0.0, -0.1), pole: float = 5.0) -> None:
        self.robot = DeltaToolModel(params, Plane(table_height, (0.0, 0.0, 1.0)), tool, pole)
        self.box, self.table = box, float(table_height)
        self._top = float(box.corners[2][1])  # top face above the centre of mass, body frame

    @property
    def u(self) -> list:
        """Servo torques (N m)."""
        return self.robot.u

    @u.setter
    def u(self, value: list) -> None:
        self.robot.u = value

    @property
    def f(self) -> list:
        """External wrist force (N, world)."""
        return self.robot.f

    @f.setter
    def f(self, value: list) -> None:
        self.robot.f = value

    # --- geometry ---------------------------------------------------------------------------
    def _tip(self, q: np.ndarray) -> tuple[float, float, tuple, tuple]:
        """Tool tip x and height above the table, and their rows over the joint angles."""
        p, ql = self.robot.params, np.asarray(q[:9], float).tolist()
        x, row_x = wrist_along(p, (1.0, 0.0, 0.0), ql)
        z, row_z = wrist_along(p, (0.0, 0.0, 1.0), ql)
        tool = self.robot.tool
        return x + tool[0], z + tool[2] - self.table, row_x, row_z

    def _face(self, q: np.ndarray) -> tuple[float, float, float, float, float, float]:
        """Box top face: normal (nx, nz), tangent (tx, tz) and the tip relative to the centre."""
        x_tip, z_tip, _, _ = self._tip(q)
        theta = float(q[11])
        c, s = math.cos(theta), math.sin(theta)
        return -s, c, c, s, x_tip - float(q[9]), z_tip - float(q[10])

    def gaps(self, q: np.ndarray) -> np.ndarray:
        """The six gaps (m), in :data:`BOX_CONTACTS` order."""
        _, z_tip, _, _ = self._tip(q)
        nx, nz, _, _, dx, dz = self._face(q)
        return np.concatenate([[z_tip, nx * dx + nz * dz - self._top], self.box.gaps(np.asarray(q[9:], float))])

    def gap_jacobian(self, q: np.ndarray) -> np.ndarray:
        """``H``, shape (6, 12)."""
        _, _, row_x, row_z = self._tip(q)
        nx, nz, tx, tz, dx, dz = self._face(q)
        H = np.zeros((6, 12))
        H[0, :9] = row_z
        H[1, :9] = nx * np.asarray(row_x) + nz * np.asarray(row_z)
        H[1, 9:] = (-nx, -nz, -(tx * dx + tz * dz))
        H[2:, 9:] = self.box.gap_jacobian(np.asarray(q[9:], float))
        return H

    def wrist_force(self, lam: np.ndarray, nx: float, nz: float) -> list[float]:
        """External wrist force plus the table's and the box's pushes on the tool (N, world)."""
        f = self.robot.f
        return [f[0] + nx * lam[1], f[1], f[2] + lam[0] + nz * lam[1]]

    # --- dynamics --------------------------------------------------------------------------
    def contact_dynamics(self, t: float, q: np.ndarray, v: np.ndarray, H: np.ndarray,
                         lam: np.ndarray) -> np.ndarray:
        """Robot (closed-loop DAE, the tool's contact forces on the wrist) and box accelerations."""
        nx, nz, _, _, _, _ = self._face(q)
        robot = self.robot
        qdd = accelerations(robot.params, q[:9], v[:9], robot.u, self.wrist_force(lam, nx, nz), robot.pole)[0]
        box = self.box.applied_forces(t, q[9:], v[9:]) + H[:, 9:].T @ lam
        return np.concatenate([qdd, box / np.diag(self.box.mass_matrix(q[9:]))])

    def contact_mobility(self, t: float, q: np.ndarray, v: np.ndarray, H: np.ndarray,
                         rows: Sequence[int]) -> np.ndarray:
        """``d v' / d lambda_i``: the robot's DAE response to the tool's push along contact i (the
        DAE is affine in the wrist force) and the box's inverse mass times its row of ``H``."""
        nx, nz, _, _, _, _ = self._face(q)
        robot = self.robot
        base = accelerations(robot.params, q[:9], v[:9], robot.u, robot.f, robot.pole)[0]
        Minv = 1.0 / np.diag(self.box.mass_matrix(q[9:]))
        columns = []
        for i in rows:
            unit = np.zeros(6)
            unit[i] = 1.0
            pushed = (accelerations(robot.params, q[:9], v[:9], robot.u, self.wrist_force(unit, nx, nz),
                                    robot.pole)[0] if i < 2 else base)
            columns.append(np.concatenate([pushed - base, Minv * H[i, 9:]]))
        return np.column_stack(columns)

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """Block diagonal: the three arms, then the box."""
        M = np.zeros((12, 12))
        M[:9, :9] = mass_matrix(self.robot.params, q[:9])
        M[9:, 9:] = self.box.mass_matrix(q[9:])
        return M

    def potential_energy(self, q: np.ndarray) -> float:
        """Gravity potential of the robot (zero in the base plane) and the box (zero on the table)."""
        return self.robot.potential_energy(q[:9]) + self.box.potential_energy(q[9:])

    def inputs_key(self, t: float, q: np.ndarray, v: np.ndarray) -> tuple:
        """The robot's inputs and the force on the box."""
        return (*self.robot.u, *self.robot.f, *np.asarray(self.box.force, float).tolist())


class BoxTableSystem(RobotContactSystem):
    """The robot's tool, the box and the table (:class:`DeltaBoxModel`), evaluated by the kernels."""

    model: DeltaBoxModel

    @property
    def params(self) -> DeltaParams:
        return self.model.robot.params

    def kernel_state(self, modes: Sequence[int] | None = None) -> BoxTable:
        model, modes = self.model, self.modes if modes is None else modes
        robot, box = model.robot, model.box
        return BoxTable(robot.tool, model.table, robot.pole, model._top, box.mass, box.inertia, box.g,
                        tuple(float(c) for c in box.corners.reshape(-1)),
                        tuple(float(c) for c in np.asarray(box.force, float)),
                        tuple(contact_law(self, i, modes[i]) for i in range(6)))

    def kernel_evaluation(self, x: np.ndarray, state: BoxTable) -> tuple:
        model = self.model
        h, hdot, lam, vdot, box, _, _, _ = box_evaluation(self.params, state, x, model.u, model.f)
        return h, hdot, lam, [*vdot, *box]

    def energy(self, x: np.ndarray) -> float:
        """Kinetic + potential + elastic energy (J), as the kernels' outputs."""
        return box_outputs(self.params, self.kernel_state(), x, self.model.u, self.model.f)[7]


def make_robot_box_contact(params: DeltaParams, table_height: float, box: BoxModel,
                           tool_material: CompliantMaterial, box_material: CompliantMaterial,
                           tool: Sequence[float] = (0.0, 0.0, -0.1), pole: float = 5.0,
                           capture_speed: float = 0.05) -> BoxTableSystem:
    """The robot, the box and the table as one contact system (state 24 values, six gaps): the
    tool's two contacts with ``tool_material``, the box's corners with ``box_material``."""
    model = DeltaBoxModel(params, table_height, box, tool, pole)
    return BoxTableSystem(model, [tool_material, tool_material] + [box_material] * 4,
                          capture_speed=capture_speed)
