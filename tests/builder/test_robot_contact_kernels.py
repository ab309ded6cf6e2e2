"""Issue 26: the robot's contact systems between events as float kernels
(deltafmi/physics/delta/contact_kernels.py), what the DeltaRobotContact and DeltaRobotBox FMUs
compile to C.

In every mode (FREE, COLLISION with a frozen effective mass, CONTACT) and with the contacts
penetrating: the kernels give the generic machine's solve (ContactSystem over the models' gaps,
numpy gap Jacobians and the DAE's accelerations) to round-off, its event indicators and energy;
and the generated C gives the kernels' Python bits exactly.
"""
from __future__ import annotations

import struct

import numpy as np
import pytest

from deltafmi.builder.codegen import Entry
from deltafmi.builder.codegen.build import compile_unit
from deltafmi.builder.codegen.kernel_types import Obj, Vec, named
from deltafmi.toolchain import NoCompilerError
from deltafmi.physics import delta as d
from deltafmi.physics.contact import CompliantMaterial, ContactSystem
from deltafmi.physics.delta import contact_kernels as ck
from deltafmi.physics.delta.box import make_robot_box_contact
from deltafmi.physics.delta.contact import Plane, make_robot_contact, robot_start_state
from deltafmi.physics.delta.params import DeltaParams
from deltafmi.physics.contact_problems.box_on_table import BoxModel

MODES = (0, 1, 2)


def plane_system(rng):
    """The tool 1 mm into a tilted plane, moving into it, with torques and a wrist force."""
    p = d.RL5
    system = make_robot_contact(p, Plane(-1.15, (0.1, -0.05, 1.0)), CompliantMaterial(2e5, 2e3, 0.4),
                                tool=(0.01, -0.02, -0.1))
    x = robot_start_state(p, [0.02, -0.01, -1.0555], [0.01, -0.02, -0.2])
    x[:9] += rng.normal(scale=1e-4, size=9)  # off the closed loops too
    system.model.u, system.model.f = list(rng.normal(size=3)), list(rng.normal(size=3))
    return system, x


def box_system(rng):
    """The tool pressing into the box top off centre, the box's bottom corners in the table, all moving."""
    p, box = d.RL5, BoxModel(2.0, 0.2, 0.1)
    system = make_robot_box_contact(p, -1.25, box, CompliantMaterial(2e5, 2e3), CompliantMaterial(1e6, 4e3, 0.3))
    robot = robot_start_state(p, [0.03, 0.0, -1.0505], [0.01, 0.01, -0.1])
    theta = 0.0
    lift = -1e-4 - float(np.min(box.rotated_corners(theta)[:, 1]))
    x = np.concatenate([robot[:9], [0.0, lift, theta], robot[9:], [0.01, -0.02, 0.3]])
    system.model.u, system.model.f = list(rng.normal(size=3)), list(rng.normal(size=3))
    return system, x


def in_mode(system, mode: int) -> None:
    """Every contact in ``mode``, collisions matched to a frozen effective mass."""
    system.modes[:] = mode
    for i in range(len(system.modes)):
        system.m_eff[i] = 1.5 + i
        system.laws[i] = system.materials[i].collision_law(system.m_eff[i])


def kernels_of(system) -> tuple[str, DeltaParams, tuple]:
    """("plane" or "box", the robot's parameters, the kernels' contacts) of a system."""
    return ("plane" if len(system.modes) == 1 else "box"), system.params, system.kernel_state()


@pytest.mark.parametrize("make", [plane_system, box_system])
@pytest.mark.parametrize("mode", MODES)
def test_kernels_are_the_machines_own_solve(make, mode):
    system, x = make(np.random.default_rng(mode))
    in_mode(system, mode)
    kernel = system._solve_unguarded(0.0, x, system.modes, None)
    generic = ContactSystem._solve_unguarded(system, 0.0, x, system.modes, None)
    pressed = kernel.h < 0.0
    assert list(np.flatnonzero(pressed)) == ([0] if len(pressed) == 1 else [1, 2, 3])
    assert np.all((kernel.lam > 0.0) == (pressed & (mode != 0)))  # only the pressed ones push, not in FREE
    for name in ("h", "hdot", "lam", "vdot"):
        a, b = getattr(kernel, name), getattr(generic, name)
        np.testing.assert_allclose(a, b, rtol=1e-11, atol=1e-11 * np.max(np.abs(b)), err_msg=name)
    for i in range(len(system.modes)):
        np.testing.assert_allclose(system._indicator_pair(i, kernel), ContactSystem._indicator_pair(system, i, generic),
                                   rtol=1e-9, atol=1e-12)
    assert system.energy(x) == pytest.approx(ContactSystem.energy(system, x), rel=1e-12)
    # the system's derivatives and indicators are the FMU kernels'
    kind, params, state = kernels_of(system)
    u, f = system.model.u, system.model.f
    np.testing.assert_array_equal(system.derivatives(0.0, x),
                                  getattr(ck, f"{kind}_derivatives")(params, state, x, u, f))
    np.testing.assert_array_equal(system.event_indicators(0.0, x),
                                  getattr(ck, f"{kind}_indicators")(params, state, x, u, f))


def bits(value) -> list:
    """Every number of a (nested) result as its IEEE-754 bits (ints as themselves)."""
    if isinstance(value, (tuple, list, np.ndarray)):
        return [b for v in value for b in bits(v)]
    return [struct.unpack("<q", struct.pack("<d", value))[0] if isinstance(value, float) else value]


@pytest.fixture(scope="module")
def compiled(tmp_path_factory):
    entries = []
    for kind, state, n in (("plane", ck.ToolPlane, 18), ("box", ck.BoxTable, 24)):
        for role in ("derivatives", "indicators", "outputs"):
            entries.append(Entry(f"{kind}_{role}", getattr(ck, f"{kind}_{role}"),
                                 [Obj(DeltaParams), named(state), Vec(n), Vec(3), Vec(3)]))
    try:
        return compile_unit(entries, tmp_path_factory.mktemp("contact_kernels"), identities=("_as_list",))
    except NoCompilerError as exc:
        pytest.skip(f"no C compiler: {exc}")


@pytest.mark.parametrize("make", [plane_system, box_system])
@pytest.mark.parametrize("mode", MODES)
def test_generated_c_gives_the_python_bits(compiled, make, mode):
    rng = np.random.default_rng(10 + mode)
    system, x = make(rng)
    in_mode(system, mode)
    kind, params, state = kernels_of(system)
    u, f = system.model.u, system.model.f
    for k in range(5):
        xk = (x + (rng.normal(scale=1e-5, size=x.size) if k else 0.0)).tolist()
        for role in ("derivatives", "indicators", "outputs"):
            python = getattr(ck, f"{kind}_{role}")(params, state, xk, u, f)
            assert bits(compiled.call(f"{kind}_{role}", params, state, xk, u, f)) == bits(python), role


@pytest.mark.parametrize("friction_mode", ["stick", "slip"])
def test_generated_c_gives_the_python_bits_with_friction(compiled, friction_mode):
    """The tool in CONTACT with Coulomb friction (deltafmi/physics/delta/tool_friction.py),
    sticking at an anchor off its position or slipping along an oblique axis: C = Python, bit for bit."""
    from deltafmi.physics.delta.tool_friction import FRICTIONLESS, tangent_basis
    from deltafmi.physics.friction.law import SLIP_POSITIVE, STICK

    rng = np.random.default_rng(20)
    system, x = plane_system(rng)
    in_mode(system, 2)
    _, params, state = kernels_of(system)
    t1, t2 = tangent_basis(state.normal)
    mode, axis = (STICK, (1.0, 0.0)) if friction_mode == "stick" else (SLIP_POSITIVE, (0.6, 0.8))
    state = state._replace(friction=state.friction._replace(mode=mode, mu_s=0.5, mu_k=0.4, viscous=30.0, t1=t1, t2=t2,
                                                           axis=axis, anchor=(0.0201, -0.0099)))
    u, f = system.model.u, system.model.f
    for k in range(5):
        xk = (x + (rng.normal(scale=1e-5, size=x.size) if k else 0.0)).tolist()
        for role in ("derivatives", "indicators", "outputs"):
            python = getattr(ck, f"plane_{role}")(params, state, xk, u, f)
            assert bits(compiled.call(f"plane_{role}", params, state, xk, u, f)) == bits(python), role
    frictionless = ck.plane_derivatives(params, state._replace(friction=FRICTIONLESS), x.tolist(), u, f)
    assert ck.plane_derivatives(params, state, x.tolist(), u, f) != frictionless  # the friction path ran
