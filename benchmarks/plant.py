"""Delta robot plant: cost per derivative evaluation, per Jacobian, and of 1 s of free fall.

Prints medians over repeats, measured in this run: accelerations() in-process, one
fmi2SetContinuousStates + fmi2GetDerivatives through fmpy, and 1 s of free fall from
z0 = (0.1, -0.1, -0.9) in Model Exchange (fmpy's CVODE) and Co-Simulation at rtol 1e-6.
Jacobians: the exact one in-process (plant_jacobian) against one derivative evaluation, and one
full Jacobian d der(x) / d [x, u] (18 x 21) through the FMU as an importer gets it: 21
fmi2GetDirectionalDerivative calls (exact derivatives) against forward and central differences
of fmi2GetDerivatives. Then the same free fall in Model Exchange through the master's CVODE with
and without the exact Jacobian (solver option jacobian), with its right-hand-side and Jacobian
evaluation counts. fmpy's own CVODE cannot use directional derivatives: its CVodeSolver never
calls CVodeSetJacFn (fmpy 0.3.x, sundials/__init__.py), so CVODE always builds its Newton matrix
from difference quotients there.
Usage: python benchmarks/plant.py [--repeats R]
"""
from __future__ import annotations

import argparse
import ctypes
import statistics
import sys
import tempfile
import time
from pathlib import Path

import fmpy
import numpy as np
from fmpy.fmi2 import FMU2Model

ROOT = Path(__file__).resolve().parents[1]
Z0 = {"z0[1]": 0.1, "z0[2]": -0.1, "z0[3]": -0.9}


def library_us(repeats: int, n: int = 3000) -> float:
    from deltafmi.physics import delta as d
    p = d.RL5
    q = d.inverse_kinematics(p, (0.1, -0.1, -0.9))
    v, u, f = np.full(9, 0.1), np.zeros(3), np.zeros(3)
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(n):
            d.accelerations(p, q, v, u, f, 5.0)
        samples.append((time.perf_counter() - start) / n * 1e6)
    return statistics.median(samples)


def fmi_derivative_us(fmu: Path, repeats: int, n: int = 3000) -> float:
    md = fmpy.read_model_description(str(fmu))
    model = FMU2Model(guid=md.guid, unzipDirectory=fmpy.extract(str(fmu)), modelIdentifier="DeltaRobot")
    model.instantiate()
    model.setupExperiment(startTime=0.0)
    model.enterInitializationMode()
    model.exitInitializationMode()
    model.newDiscreteStates()
    model.enterContinuousTimeMode()
    x, dx = np.zeros(18), np.zeros(18)
    px, pdx = (a.ctypes.data_as(ctypes.POINTER(ctypes.c_double)) for a in (x, dx))
    model.getContinuousStates(px, 18)
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        for k in range(n):
            x[9] = 1e-6 * k  # a new state each time: no cached evaluation
            model.setContinuousStates(px, 18)
            model.getDerivatives(pdx, 18)
        samples.append((time.perf_counter() - start) / n * 1e6)
    model.terminate()
    model.freeInstance()
    return statistics.median(samples)


def _started(fmu: Path) -> tuple:
    md = fmpy.read_model_description(str(fmu))
    model = FMU2Model(guid=md.guid, unzipDirectory=fmpy.extract(str(fmu)), modelIdentifier="DeltaRobot")
    model.instantiate()
    model.setupExperiment(startTime=0.0)
    model.enterInitializationMode()
    model.exitInitializationMode()
    model.newDiscreteStates()
    model.enterContinuousTimeMode()
    return md, model


def jacobian_in_process_us(repeats: int, n: int = 300) -> float:
    from deltafmi.physics import delta as d
    from deltafmi.physics.delta.jacobian import plant_jacobian
    p = d.RL5
    q = d.inverse_kinematics(p, (0.1, -0.1, -0.9))
    v, u, f = np.full(9, 0.1), np.zeros(3), np.zeros(3)
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(n):
            plant_jacobian(p, q, v, u, f, 5.0)
        samples.append((time.perf_counter() - start) / n * 1e6)
    return statistics.median(samples)


def fmu_jacobian_us(fmu: Path, repeats: int, n: int = 100) -> dict:
    """One full 18 x 21 Jacobian through the FMU: directional derivatives, forward and central
    differences, each from a new state (no cached evaluation helps)."""
    from fmpy.fmi2 import fmi2Real, fmi2ValueReference
    md, model = _started(fmu)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    derivatives = [u.variable.valueReference for u in md.derivatives]
    knowns = [u.variable.derivative.valueReference for u in md.derivatives] + [vr[f"u[{i}]"] for i in (1, 2, 3)]
    handle, dll = model.component, model.dll
    unknown_refs = (fmi2ValueReference * 18)(*derivatives)
    seed = (fmi2Real * 1)(1.0)
    J = np.zeros((21, 18))  # row j: column j of the Jacobian
    columns = [((fmi2ValueReference * 1)(k), J[j].ctypes.data_as(ctypes.POINTER(ctypes.c_double)))
               for j, k in enumerate(knowns)]
    x, dx, base = np.zeros(18), np.zeros(18), np.zeros(18)
    px, pdx, pbase = (a.ctypes.data_as(ctypes.POINTER(ctypes.c_double)) for a in (x, dx, base))
    model.getContinuousStates(px, 18)
    x[9:] = 0.1
    u_vrs = (fmi2ValueReference * 3)(*knowns[18:])
    u = (fmi2Real * 3)(0.0, 0.0, 0.0)

    def exact(k: int) -> None:
        x[0] += 1e-9
        dll.fmi2SetContinuousStates(handle, px, 18)
        for known, out in columns:
            dll.fmi2GetDirectionalDerivative(handle, unknown_refs, 18, known, 1, seed, out)

    def differences(k: int, central: bool) -> None:
        x[0] += 1e-9
        x0 = x.copy()
        if not central:
            dll.fmi2SetContinuousStates(handle, px, 18)
            dll.fmi2GetDerivatives(handle, pbase, 18)
        for j in range(21):
            for sign in ((1.0, -1.0) if central else (1.0,)):
                if j < 18:
                    x[j] = x0[j] + sign * 1e-7
                    dll.fmi2SetContinuousStates(handle, px, 18)
                else:
                    u[j - 18] = sign * 1e-7
                    dll.fmi2SetReal(handle, u_vrs, 3, u)
                dll.fmi2GetDerivatives(handle, pdx, 18)
                x[:] = x0
                u[0] = u[1] = u[2] = 0.0
            if j >= 18:
                dll.fmi2SetReal(handle, u_vrs, 3, u)

    result = {}
    for name, run in (("exact", exact), ("forward", lambda k: differences(k, False)),
                      ("central", lambda k: differences(k, True))):
        samples = []
        for _ in range(repeats):
            start = time.perf_counter()
            for k in range(n):
                run(k)
            samples.append((time.perf_counter() - start) / n * 1e6)
        result[name] = statistics.median(samples)
    model.terminate()
    model.freeInstance()
    return result


def master_free_fall(fmu: Path, jacobian: bool, repeats: int) -> tuple:
    """1 s of free fall in Model Exchange through the master's CVODE at rtol 1e-6: (median
    seconds of stepping, after the set-up; right-hand sides; Jacobians) with or without the FMU's
    exact Jacobian."""
    from deltafmi.master.stepping import me_integrator
    from deltafmi.master.stepping.master import Master
    from deltafmi import resolve_system
    from deltafmi.master.scenario.spec import load_scenario

    counts = {"rhs": 0, "jac": 0}
    original_rhs, original_jac = me_integrator.ModelExchangeUnit._rhs, me_integrator.ModelExchangeUnit._jacobian

    def rhs(self, *args):
        counts["rhs"] += 1
        return original_rhs(self, *args)

    def jac(self, *args):
        counts["jac"] += 1
        return original_jac(self, *args)

    samples = []
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fall.yaml"
        path.write_text(f"""experiment: {{start: 0.0, stop: 1.0, step: 1.0e-2}}
components:
  plant: {{fmu: {fmu}, interface: ME, parameters: {{z0: [0.1, -0.1, -0.9]}},
           solver: {{rtol: 1.0e-6, jacobian: {str(jacobian).lower()}}}}}
outputs: ['plant.z[3]']
""")
        system = resolve_system(load_scenario(path))
        me_integrator.ModelExchangeUnit._rhs, me_integrator.ModelExchangeUnit._jacobian = rhs, jac
        try:
            for _ in range(repeats):
                counts.update(rhs=0, jac=0)
                summary = Master(system, result=Path(tmp) / "fall.csv").run()
                samples.append(summary.wall_time - summary.setup_time)  # the stepping only
        finally:
            me_integrator.ModelExchangeUnit._rhs, me_integrator.ModelExchangeUnit._jacobian = original_rhs, original_jac
    return statistics.median(samples), counts["rhs"], counts["jac"]


def free_fall_seconds(fmu: Path, fmi_type: str, repeats: int) -> float:
    directory = fmpy.extract(str(fmu))  # unzip once: the figure is simulation time
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        fmpy.simulate_fmu(directory, fmi_type=fmi_type, stop_time=1.0, relative_tolerance=1e-6,
                          output_interval=1e-2, start_values=Z0, output=["z[3]"])
        samples.append(time.perf_counter() - start)
    return statistics.median(samples)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    from deltafmi.builder import build_fmu
    with tempfile.TemporaryDirectory() as tmp:
        fmu = build_fmu(ROOT / "fmu_src" / "delta_robot.py", Path(tmp) / "DeltaRobot.fmu")
        lib = library_us(args.repeats)
        fmi = fmi_derivative_us(fmu, args.repeats)
        me = free_fall_seconds(fmu, "ModelExchange", args.repeats)
        cs = free_fall_seconds(fmu, "CoSimulation", args.repeats)
        jac = jacobian_in_process_us(args.repeats)
        fmu_jac = fmu_jacobian_us(fmu, args.repeats)
        with_jac = master_free_fall(fmu, True, args.repeats)
        without = master_free_fall(fmu, False, args.repeats)
    print(f"DeltaRobot plant, medians of {args.repeats} runs")
    print(f"  accelerations() in-process               {lib:8.2f} us")
    print(f"  setContinuousStates + getDerivatives     {fmi:8.2f} us  (through fmpy and the FMU)")
    print(f"  1 s free fall, ME (fmpy CVODE, rtol 1e-6) {me * 1e3:7.1f} ms  real-time factor {1 / me:6.1f}")
    print(f"  1 s free fall, CS (internal CVODE)        {cs * 1e3:7.1f} ms  real-time factor {1 / cs:6.1f}")
    print("Jacobians")
    print(f"  plant_jacobian() in-process (18 x 24, exact) {jac:8.2f} us  = {jac / lib:5.1f} derivative evaluations")
    print(f"  18 x 21 through the FMU: 21 directional derivatives {fmu_jac['exact']:8.1f} us")
    print(f"                           forward differences (22 evaluations) {fmu_jac['forward']:8.1f} us"
          f"  ratio {fmu_jac['forward'] / fmu_jac['exact']:5.2f}")
    print(f"                           central differences (42 evaluations) {fmu_jac['central']:8.1f} us"
          f"  ratio {fmu_jac['central'] / fmu_jac['exact']:5.2f}")
    print("1 s free fall, ME through the master's CVODE (rtol 1e-6)")
    for name, (seconds, rhs, jacs) in (("exact Jacobian (directional derivatives)", with_jac),
                                        ("CVODE's difference quotients", without)):
        print(f"  {name:42s} {seconds * 1e3:7.1f} ms  {rhs:5d} right-hand sides, {jacs:3d} Jacobians")
    print(f"  ratio without / with                       {without[0] / with_jac[0]:7.2f}")


if __name__ == "__main__":
    sys.exit(main())
