"""Per-piece cost of the flagship's FMUs through FMI against the same code called in-process.

The flagship (scenarios/delta_tracking.yaml) pays, per 1 ms step, four plant right-hand sides
(rk4 in Model Exchange), one trajectory doStep and one controller doStep. Each is timed here
through the FMU's own fmi2 functions, the FMU loaded by fmpy in this process, and against the
same Python object the FMU runs (its compiled kernels, its path, its controller) called directly:

- plant RHS: fmi2SetTime + fmi2SetContinuousStates + fmi2GetDerivatives, looped in C by the
  master's Runge-Kutta kernel (deltafmi.master.stepping.explicit_rk, Euler, one RHS per step), against
  ``state_derivative(params, x, u, f, pole)``;
- trajectory: fmi2DoStep + fmi2GetReal(r, rd, rdd), against ``path.evaluate(t)``;
- controller: fmi2SetReal(y, yd, r, rd, rdd) + fmi2DoStep + fmi2GetReal(u), against ``ctl.step``.

The FMI calls go through ctypes function pointers with prepared arguments (what the master's
C loops and batched transfers pay), so fmpy's per-call Python wrappers are left out.
Usage: python benchmarks/fmi_pieces.py [--repeats R]
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
from fmpy.fmi2 import FMU2Model, FMU2Slave

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "delta_tracking.yaml"


def paired_us(through_fmi, in_process, calls: int, repeats: int) -> tuple[float, float, float]:
    """Medians of us per call of both, and of their ratio, timed alternately so that both see
    the same machine (the ratio of each pair is immune to slow phases of a shared machine)."""
    fmi, floor, ratio = [], [], []
    for _ in range(repeats):
        pair = []
        for function in (through_fmi, in_process):
            start = time.perf_counter()
            function(calls)
            pair.append((time.perf_counter() - start) / calls * 1e6)
        fmi.append(pair[0])
        floor.append(pair[1])
        ratio.append(pair[0] / pair[1])
    return statistics.median(fmi), statistics.median(floor), statistics.median(ratio)


def built(source: str, workdir: Path) -> tuple[Path, object]:
    from deltafmi.builder import build_fmu
    fmu = build_fmu(ROOT / "fmu_src" / source, workdir / Path(source).with_suffix(".fmu").name)
    return fmu, fmpy.read_model_description(str(fmu))


def component_of(slave) -> object:
    """The Python component behind an fmpy-loaded deltafmi FMU instance (for the in-process floor)."""
    registry = sys.modules["_deltafmi_fmu_registry"]
    resources = str(Path(slave.unzipDirectory, "resources").resolve())
    return registry.loaded[resources][1]  # the component class, imported with the FMU's runtime


def vrs(md, *names: str) -> list[int]:
    by_name = {v.name: v.valueReference for v in md.modelVariables}
    out = []
    for name in names:
        out += [by_name[n] for n in by_name if n == name or n.startswith(name + "[")]
    return out


def plant_piece(workdir: Path, repeats: int) -> tuple[float, float]:
    from deltafmi.master.stepping.explicit_rk import ExplicitRungeKutta
    fmu, md = built("delta_robot.py", workdir)
    m = FMU2Model(guid=md.guid, unzipDirectory=fmpy.extract(str(fmu)),
                  modelIdentifier=md.modelExchange.modelIdentifier, instanceName="plant")
    m.instantiate()
    m.setupExperiment(startTime=0.0)
    m.setReal(vrs(md, "u"), [20.0, 18.0, 19.0])
    m.enterInitializationMode()
    m.exitInitializationMode()
    m.newDiscreteStates()
    m.enterContinuousTimeMode()
    x0 = np.zeros(18)
    m.getContinuousStates(x0.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), 18)
    erk = ExplicitRungeKutta(m, x0, 0.0, method="euler")
    x = x0.copy()

    module = sys.modules[component_of(m).__module__]
    params = module.delta.DeltaParams()
    u, f, xs = np.array([20.0, 18.0, 19.0]), np.zeros(3), x0.copy()
    dx = np.zeros(18)
    reference = np.zeros(18)
    m.setContinuousStates(x0.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), 18)
    m.getDerivatives(reference.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), 18)
    assert np.allclose(module.delta.state_derivative(params, xs, u, f, 5.0), reference, rtol=0, atol=1e-12)

    def direct(n: int) -> None:
        for _ in range(n):
            dx[:] = module.delta.state_derivative(params, xs, u, f, 5.0)
    result = paired_us(lambda n: erk._run(0.0, 1e-9, n, x), direct, 2000, repeats)
    m.terminate()
    m.freeInstance()
    return result


def prepared(slave, md, inputs: list[int], outputs: list[int]):
    """ctypes calls with prepared arguments: set inputs, doStep, get outputs."""
    dll, c = slave.dll, slave.component
    set_real, do_step, get_real = dll.fmi2SetReal, dll.fmi2DoStep, dll.fmi2GetReal
    n_in, n_out = len(inputs), len(outputs)
    vin, vout = (ctypes.c_uint * n_in)(*inputs), (ctypes.c_uint * n_out)(*outputs)
    xin, xout = (ctypes.c_double * n_in)(), (ctypes.c_double * n_out)()
    return set_real, do_step, get_real, c, vin, n_in, xin, vout, n_out, xout


def trajectory_piece(workdir: Path, repeats: int) -> tuple[float, float]:
    import yaml
    fmu, md = built("trajectory.py", workdir)
    s = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(fmu)),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="trajectory")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    params = yaml.safe_load(SCENARIO.read_text())["components"]["trajectory"]["parameters"]
    for name, value in params.items():
        values = value if isinstance(value, list) else [value]
        refs = vrs(md, name)
        (s.setInteger if isinstance(values[0], int) else s.setReal)(refs, values)
    s.enterInitializationMode()
    s.exitInitializationMode()
    _, do_step, get_real, c, _, _, _, vout, n_out, xout = prepared(s, md, [], vrs(md, "r", "rd", "rdd"))
    do_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int]
    state = {"t": 0.0}

    def through_fmi(n: int) -> None:
        t, h = state["t"], 1e-3
        for _ in range(n):
            do_step(c, t, h, 1)
            get_real(c, vout, n_out, xout)
            t += h
        state["t"] = t
    path = _instance_component(s)._path

    def direct(n: int) -> None:
        t = state["t"] - n * 1e-3  # the same stretch of the path as the FMU just stepped through
        for _ in range(n):
            path.evaluate(t)
            t += 1e-3
    result = paired_us(through_fmi, direct, 200, repeats)
    s.terminate()
    s.freeInstance()
    return result


def _instance_component(slave):
    """The live component object of an instance (only for the floor: reads its path/controller)."""
    import gc
    cls = component_of(slave)
    live = [o for o in gc.get_objects() if isinstance(o, cls)]
    return live[-1]


def controller_piece(workdir: Path, repeats: int) -> tuple[float, float]:
    fmu, md = built("delta_controller.py", workdir)
    s = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(fmu)),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="controller")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    inputs = vrs(md, "y", "yd", "r", "rd", "rdd")
    set_real, do_step, get_real, c, vin, n_in, xin, vout, n_out, xout = prepared(s, md, inputs, vrs(md, "u"))
    do_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int]
    # the robot at rest at z = -1 (servo angles from its inverse kinematics), reference there
    component = _instance_component(s)
    module = sys.modules[type(component).__module__]
    from_kin = sys.modules[module.delta_control.__name__.rsplit(".", 1)[0] + ".kinematics"]
    q0 = from_kin.inverse_kinematics(module.delta_params.RL5, [0.0, 0.0, -1.0])
    y = [float(q0[0]), float(q0[3]), float(q0[6])]
    values = y + [0.0] * 3 + [0.0, 0.0, -1.0] + [0.0] * 6
    for i, v in enumerate(values):
        xin[i] = v
    state = {"t": 0.0}

    def through_fmi(n: int) -> None:
        t, h = state["t"], 1e-3
        for _ in range(n):
            set_real(c, vin, n_in, xin)
            do_step(c, t, h, 1)
            get_real(c, vout, n_out, xout)
            t += h
        state["t"] = t
    ctl = component._ctl
    args = (y, [0.0] * 3, [0.0, 0.0, -1.0], [0.0] * 3, [0.0] * 3, [0.0] * 3, 0.0)

    def direct(n: int) -> None:
        for _ in range(n):
            ctl.step(*args)
    result = paired_us(through_fmi, direct, 200, repeats)
    s.terminate()
    s.freeInstance()
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=31)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        workdir = Path(tmp)
        rows = [("plant RHS (SetTime+SetContinuousStates+GetDerivatives)", *plant_piece(workdir, args.repeats)),
                ("trajectory (DoStep+GetReal 9)", *trajectory_piece(workdir, args.repeats)),
                ("controller (SetReal 15+DoStep+GetReal 3)", *controller_piece(workdir, args.repeats))]
    print(f"Flagship pieces, medians of {args.repeats} runs (us per call)")
    print(f"  {'piece':58s} {'FMI':>8s} {'in-process':>10s} {'ratio':>6s} {'overhead':>8s}")
    for name, fmi, floor, ratio in rows:
        print(f"  {name:58s} {fmi:8.2f} {floor:10.2f} {ratio:6.2f} {fmi - floor:8.2f}")


if __name__ == "__main__":
    main()
