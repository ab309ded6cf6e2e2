"""CVODE's projection as a compiled kernel (``NativeKernels(project=...)``): the Co-Simulation
solver of a constrained plant projects onto its manifold after every internal step in C.

The compiled projection must give the Python projection's states bit for bit (the generated C
performs the kernel's float operations in Python's order, and the correction CVODE adds is
projected - y in both): whole CS runs with it on, with only the projection in Python
(``DELTAFMI_NATIVE_PROJECT=0``) and with every kernel off (``DELTAFMI_NATIVE=0``) are compared
with ``array_equal``. That the C projection really runs is shown by a test component (a particle
on a ring) whose Python ``project`` counts its calls; its motion is checked against the closed
form. The delta robot's loops stay closed to <= 1e-9 m after every step, and a reset loop of its
CS FMU keeps the resident memory flat.
"""
from __future__ import annotations

import json
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import simulate_fmu
from test_memory import CYCLES, LIMIT
from test_memory import SCRIPT as MEMORY_SCRIPT

from deltafmi.builder import build_fmu

ROOT = Path(__file__).resolve().parents[2]
MODES = {"compiled": {}, "python projection": {"DELTAFMI_NATIVE_PROJECT": "0"}, "python": {"DELTAFMI_NATIVE": "0"}}

RING = textwrap.dedent('''
    """A particle on a ring (radius R, no gravity): the Baumgarte-stabilised DAE in Cartesian
    coordinates, projected onto the ring after every CVODE step by a compiled kernel."""
    import math
    from dataclasses import dataclass
    from typing import Sequence

    from deltafmi.component import Component, Experiment, Kernel, NativeKernels, Output, Parameter, State


    @dataclass(frozen=True)
    class Ring:
        radius: float
        pole: float
        limit: float


    def ring_derivatives(ring: Ring, s: Sequence[float]) -> list[float]:
        """a = -lam p with lam from c'' + 2 k c' + k^2 c = 0, c = (|p|^2 - R^2) / 2."""
        x, y, vx, vy = s[0], s[1], s[2], s[3]
        c, cd = 0.5 * (x * x + y * y - ring.radius * ring.radius), x * vx + y * vy
        lam = (vx * vx + vy * vy + 2.0 * ring.pole * cd + ring.pole * ring.pole * c) / (x * x + y * y)
        return [vx, vy, -lam * x, -lam * y]


    def ring_projection(ring: Ring, s: Sequence[float]) -> list[float]:
        """p onto the ring (R p / |p|), v onto its tangent; a drift beyond limit is an error."""
        r = math.sqrt(s[0] * s[0] + s[1] * s[1])
        if abs(r - ring.radius) > ring.limit:
            raise ArithmeticError(f"the particle drifted {r - ring.radius} m off the ring")
        ux, uy = s[0] / r, s[1] / r
        radial = s[2] * ux + s[3] * uy
        return [ring.radius * ux, ring.radius * uy, s[2] - radial * ux, s[3] - radial * uy]


    class RingParticle(Component):
        """A particle moving on a ring at constant speed (no forces but the ring's)."""

        default_experiment = Experiment(stop=2.0, step=0.01, tolerance=1e-10)
        radius = Parameter(0.5, unit="m", description="Ring radius")
        pole = Parameter(5.0, unit="1/s", description="Baumgarte pole")
        limit = Parameter(1e-3, unit="m", description="Largest drift the projection accepts")
        s = State([0.5, 0.0, 0.0, 1.0], description="Position and velocity")
        python_projections = Output(0, type=int, description="Calls of the Python projection so far")

        native = NativeKernels(derivatives=Kernel(ring_derivatives, "_ring", "states"),
                               project=Kernel(ring_projection, "_ring", "states"),
                               attributes={"_ring": Ring})

        def setup(self) -> None:
            self._ring = None
            self._projections = 0

        def initialize(self, t: float) -> None:
            self._ring = Ring(self.radius, self.pole, self.limit)

        def derivatives(self, t: float) -> list:
            return ring_derivatives(self._ring, self.states.tolist())

        def project(self, t: float) -> None:
            self._projections += 1
            self.states[:] = ring_projection(self._ring, self.states.tolist())

        def outputs(self, t: float) -> None:
            self.python_projections = self._projections
''')


def _run(fmu: Path, mode: str, monkeypatch, **kwargs) -> np.ndarray:
    for name in ("DELTAFMI_NATIVE", "DELTAFMI_NATIVE_PROJECT"):
        monkeypatch.delenv(name, raising=False)
    for name, value in MODES[mode].items():
        monkeypatch.setenv(name, value)
    return simulate_fmu(str(fmu), fmi_type="CoSimulation", **kwargs)


@pytest.fixture(scope="module")
def ring_fmus(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ring")
    (folder / "ring.py").write_text(RING)
    return {version: build_fmu(folder / "ring.py", folder / f"Ring{version}.fmu", fmi_version=version)
            for version in (2, 3)}


@pytest.mark.parametrize("version", [2, 3])
def test_the_compiled_projection_runs_and_equals_the_python_one_bit_for_bit(ring_fmus, version, monkeypatch):
    states = ["s[1]", "s[2]", "s[3]", "s[4]"] if version == 2 else ["s"]  # FMI 3.0: one array variable
    runs = {mode: _run(ring_fmus[version], mode, monkeypatch, output_interval=0.01,
                       output=[*states, "python_projections"]) for mode in MODES}
    for mode in ("python projection", "python"):
        for name in states:
            assert np.array_equal(runs["compiled"][name], runs[mode][name]), (mode, name)
        # CVODE projects after each of its internal steps: hundreds over 2 s
        assert runs[mode]["python_projections"][-1] > 100
    assert runs["compiled"]["python_projections"][-1] == 0


def test_the_projected_particle_follows_the_circle_in_closed_form(ring_fmus, monkeypatch):
    result = _run(ring_fmus[2], "compiled", monkeypatch, output_interval=0.01, output=["s[1]", "s[2]", "s[3]", "s[4]"])
    t, omega, radius = result["time"], 1.0 / 0.5, 0.5  # speed 1 m/s on R = 0.5 m: omega = 2 rad/s
    # projected after every step: on the ring to rounding (a few ulps of R), tangent velocity
    assert np.max(np.abs(np.hypot(result["s[1]"], result["s[2]"]) - radius)) < 1e-15
    assert np.max(np.abs(result["s[1]"] * result["s[3]"] + result["s[2]"] * result["s[4]"])) < 1e-15
    # the only error left is the phase: CVODE keeps each of its ~320 steps' local error below
    # rtol |x| + atol = 1e-10 * 0.5 + 1e-10 (nominal 1) = 1.5e-10 m; their sum bounds the drift
    # along the ring by 5e-8 m (measured 2.2e-9 m)
    assert np.max(np.abs(result["s[1]"] - radius * np.cos(omega * t))) < 5e-8
    assert np.max(np.abs(result["s[2]"] - radius * np.sin(omega * t))) < 5e-8


def test_a_raising_projection_hands_the_call_to_python_which_explains(ring_fmus, monkeypatch, capfd):
    """A kernel that raises returns its line to C, which calls the Python projection: that one
    raises with its message (the same kernel), and the step fails with it in the log (fmpy's
    default logger prints it: its logger= would stay process-wide, see test_native_kernels.py)."""
    with pytest.raises(Exception, match="fmi2DoStep failed"):
        _run(ring_fmus[2], "compiled", monkeypatch, output_interval=0.01, start_values={"limit": 0.0})
    printed = "".join(capfd.readouterr())
    assert "ArithmeticError: the particle drifted" in printed and "m off the ring" in printed, printed[-2000:]


@pytest.fixture(scope="module")
def plant_fmus(tmp_path_factory):
    folder = tmp_path_factory.mktemp("plants")
    return {name: build_fmu(ROOT / "fmu_src" / f"{name}.py", folder / f"{name}.fmu")
            for name in ("delta_robot", "delta_wrist")}


#: servo torques that swing the robot across its workspace, wrist torques that spin the wrist
PLANTS = {"delta_robot": ({"u[1]": 5.0, "u[2]": -3.0, "u[3]": 1.0}, ["q[1]", "q[5]", "v[9]"]),
          "delta_wrist": ({"u[1]": 5.0, "u[2]": -3.0, "u[3]": 1.0, "tau[1]": 0.02, "tau[2]": -0.01, "qw0[1]": 0.3,
                           "qw0[2]": -0.4}, ["q[1]", "q[5]", "v[9]", "q_w[2]", "v_w[3]", "energy"])}


@pytest.mark.parametrize("plant", sorted(PLANTS))
def test_the_plants_compiled_projection_equals_the_python_one_and_closes_the_loops(plant_fmus, plant, monkeypatch):
    start, names = PLANTS[plant]
    runs = {mode: _run(plant_fmus[plant], mode, monkeypatch, stop_time=0.5, output_interval=1e-3,
                       start_values=start, output=[*names, "residual"]) for mode in MODES}
    for mode in ("python projection", "python"):
        for name in (*names, "residual"):
            assert np.array_equal(runs["compiled"][name], runs[mode][name]), (plant, mode, name)
    # the robot really moves (the servos swing it), and after every 1 ms step the loops are closed:
    # the projection iterates to |h| <= 1e-13 m, the bound is 1e-9 m
    assert np.ptp(runs["compiled"]["q[1]"]) > 0.1
    assert np.max(runs["compiled"]["residual"]) <= 1e-9


def test_resident_memory_stays_flat_over_reset_cycles_with_the_compiled_projection(plant_fmus):
    """Each fmi2Reset cycle (3 CS steps) builds a CVODE with the compiled projection's user data
    (tests/runtime/test_memory.py's script and bound: allocator noise is tens of bytes per cycle, a leaked
    solver kilobytes)."""
    fmu = plant_fmus["delta_robot"]
    with zipfile.ZipFile(fmu) as archive:
        assert "project" in json.loads(archive.read("resources/native_kernels.json"))["kernels"]
    out = subprocess.run([sys.executable, "-c", MEMORY_SCRIPT, str(fmu), "reset", str(CYCLES)], capture_output=True,
                         text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    per_cycle = float(out.stdout.strip())
    assert per_cycle < LIMIT, f"{per_cycle:.0f} bytes per reset cycle"


def test_a_projection_that_returns_no_state_or_runs_without_derivatives_is_named():
    from deltafmi.component import Component, Kernel, NativeKernels, Output, State
    from deltafmi.builder.codegen.component_kernels import generate_component
    from deltafmi.builder.codegen.kernel_types import CodegenError

    def keep(x: list) -> list:
        return [x[0]]

    class Drifting(Component):
        x = State(1.0)
        y = Output()
        native = NativeKernels(derivatives=Kernel(keep, "states"), project=Kernel(keep, "states", returns=("y",)))

        def project(self, t: float) -> None:
            pass

    with pytest.raises(CodegenError, match="project returns 'y', which is not a state"):
        generate_component(Drifting)

    class Projecting(Drifting):
        native = NativeKernels(project=Kernel(keep, "states"))

    with pytest.raises(CodegenError, match="Projecting.native: a project kernel is CVODE's projection, which runs "
                                           "with the compiled right-hand side: declare the derivatives kernel too"):
        generate_component(Projecting)


def test_the_wrist_plants_projection_kernel_is_its_mechanics_projection():
    """DeltaWrist's kernel (the codegen subset: new tuples for in-place list updates, J_s^T dzd as
    dot products, sqrt(sum h^2) for math.hypot) against deltafmi.physics.delta_wrist's numpy
    projection at drifted states of a moving robot with a swinging wrist: the same operations but
    numpy's matmul (which may round its 3-term sums otherwise: a few ulps of the rates, ~1e-15)."""
    from deltafmi.physics import delta_wrist
    from deltafmi.physics.delta.params import DeltaParams
    from deltafmi.physics.delta_wrist import dynamics
    from deltafmi.physics.delta_wrist.params import WristMount
    from deltafmi.physics.wrist.kernels import wrist_constants
    from deltafmi.models.delta_wrist import project_state

    p = DeltaParams()
    w = wrist_constants(delta_wrist.wrist_params((3e-4, 2e-4, 1e-4), delta_wrist.peg_tool(0.25, 0.1, 0.01, 0.13),
                                                 9.81, 0.0))
    x0 = dynamics.start_state(p, w, WristMount(0.0, 0.0, -0.05), [0.05, -0.03, -1.15], [0.3, -0.2, 0.5],
                              zd=[0.2, -0.1, 0.3], qwd=[1.0, -2.0, 0.5])
    rng = np.random.default_rng(7)
    for _ in range(50):
        x = x0 + rng.normal(size=24) * 1e-6  # an integrator's drift and more
        projected = np.array(project_state(p, w, x.tolist()))
        np.testing.assert_allclose(projected, dynamics.project_to_constraints(p, w, x), rtol=0, atol=1e-13)
        assert dynamics.loop_residual(p, projected) <= 1e-13
