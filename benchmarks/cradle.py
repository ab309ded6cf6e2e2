"""Newton's cradle side by side: deltafmi's multi-mode contact, pybullet and MuJoCo.

The same touching free chain (unit masses, radius 0.02 m, no gravity along the line), the striker
at 1 m/s, perfectly elastic contact. Prints the ball velocities after the collisions, the momentum
and energy errors and the wall time. The ideal answer is (0, ..., 0, 1).

    python benchmarks/cradle.py            # 3 and 5 balls
    python benchmarks/cradle.py --balls 7

pybullet and MuJoCo are optional (``pip install pybullet mujoco``); a missing one prints
``skipped: <reason>``.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Callable, Optional

import numpy as np

#: the tests' reference driver of FMI Model-Exchange event semantics (tests/hybrid_sim.py)
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

MASS, RADIUS, SPEED, T_END = 1.0, 0.02, 1.0, 0.05


def ours(n: int, exponent: float) -> tuple[np.ndarray, float]:
    """deltafmi.physics: compliant two-body impacts (collision duration 1e-4 s at 1 m/s)."""
    from deltafmi.physics.contact.collision_law import CollisionLaw
    from hybrid_sim import simulate
    from deltafmi.physics.contact_problems.newtons_cradle import make_cradle

    system, x0 = make_cradle(n, mass=MASS, radius=RADIUS, striker_speed=SPEED,
                             law=CollisionLaw(restitution=1.0, duration=1e-4, exponent=exponent))
    start = time.perf_counter()
    result = simulate(system, (0.0, T_END), x0, rtol=1e-9, atol=1e-12)
    wall = time.perf_counter() - start
    return system.model.ball_velocities(result.x[-1]), wall


def pybullet_run(n: int) -> tuple[np.ndarray, float]:
    """pybullet (Bullet's sequential-impulse LCP solver), restitution 1, dt 1e-4 s."""
    import pybullet as pb

    dt = 1e-4
    client = pb.connect(pb.DIRECT)
    try:
        pb.setGravity(0, 0, 0, physicsClientId=client)
        pb.setTimeStep(dt, physicsClientId=client)
        pb.setPhysicsEngineParameter(restitutionVelocityThreshold=0.0, numSolverIterations=200,
                                     physicsClientId=client)
        shape = pb.createCollisionShape(pb.GEOM_SPHERE, radius=RADIUS, physicsClientId=client)
        bodies = []
        for i in range(n):
            body = pb.createMultiBody(baseMass=MASS, baseCollisionShapeIndex=shape,
                                      basePosition=[2 * RADIUS * i, 0, 0], physicsClientId=client)
            pb.changeDynamics(body, -1, restitution=1.0, lateralFriction=0.0, linearDamping=0.0,
                              angularDamping=0.0, physicsClientId=client)
            bodies.append(body)
        pb.resetBaseVelocity(bodies[0], [SPEED, 0, 0], physicsClientId=client)
        start = time.perf_counter()
        for _ in range(int(round(T_END / dt))):
            pb.stepSimulation(physicsClientId=client)
        wall = time.perf_counter() - start
        v = np.array([pb.getBaseVelocity(b, physicsClientId=client)[0][0] for b in bodies])
    finally:
        pb.disconnect(physicsClientId=client)
    return v, wall


def mujoco_run(n: int) -> tuple[np.ndarray, float]:
    """MuJoCo soft contact made elastic (solref = -1e7 0: stiffness, zero damping), RK4, dt 1e-5 s."""
    import mujoco

    dt = 1e-5
    bodies = "".join(
        f'<body pos="{2 * RADIUS * i} 0 0"><joint type="slide" axis="1 0 0"/>'
        f'<geom type="sphere" size="{RADIUS}" mass="{MASS}" condim="1" solref="-1e7 0" '
        f'solimp="0.99 0.99 0.001"/></body>' for i in range(n))
    xml = (f'<mujoco><option timestep="{dt}" gravity="0 0 0" integrator="RK4"/>'
           f'<worldbody>{bodies}</worldbody></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qvel[0] = SPEED
    start = time.perf_counter()
    for _ in range(int(round(T_END / dt))):
        mujoco.mj_step(model, data)
    return data.qvel.copy(), time.perf_counter() - start


def row(name: str, n: int, run: Callable[[int], tuple[np.ndarray, float]]) -> Optional[str]:
    """One table row, or a 'skipped' line when the engine is not installed."""
    try:
        v, wall = run(n)
    except ImportError as exc:
        return f"{name:<22} {n:>2}  skipped: {exc}"
    p0, e0 = MASS * SPEED, 0.5 * MASS * SPEED ** 2
    dp = (MASS * v.sum() - p0) / p0
    de = (0.5 * MASS * float(v @ v) - e0) / e0
    vel = " ".join(f"{x:+.4f}" for x in v)
    return f"{name:<22} {n:>2}  {vel:<48} {dp:+.1e}  {de:+.1e}  {wall * 1e3:8.1f}"


def main() -> None:
    """Print the comparison table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--balls", type=int, nargs="+", default=[3, 5])
    args = parser.parse_args()
    engines = [
        ("deltafmi (cubic p=3)", lambda n: ours(n, 3.0)),
        ("deltafmi (Hertz p=1.5)", lambda n: ours(n, 1.5)),
        ("pybullet", pybullet_run),
        ("mujoco", mujoco_run),
    ]
    print(f"Touching free chain, unit masses, striker {SPEED} m/s, elastic; ideal: 0 ... 0 1")
    print(f"{'engine':<22} {'n':>2}  {'velocities after the collisions (m/s)':<48} "
          f"{'d momentum':>8}  {'d energy':>8}  {'wall ms':>8}")
    for n in args.balls:
        for name, run in engines:
            print(row(name, n, run))


if __name__ == "__main__":
    main()
