"""The equation-compiled delta robot's right-hand side through FMI against the hand-written plant's.

Both FMUs in Model Exchange through fmpy: fmi2SetContinuousStates + fmi2GetDerivatives at a
state on the closed loops, medians of 11 interleaved runs of 20,000 calls each, and the ratio.
Run: python benchmarks/equations.py
"""
import ctypes
import statistics
import time

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Model

from deltafmi.builder.packager import build_cached
from deltafmi.physics import delta
from deltafmi.physics.delta.params import RL5


def instance(name):
    path = build_cached(name)
    md = read_model_description(path)
    m = FMU2Model(guid=md.guid, unzipDirectory=extract(path), modelIdentifier=md.modelExchange.modelIdentifier,
                  instanceName=name)
    m.instantiate()
    m.setupExperiment(startTime=0.0)
    m.enterInitializationMode()
    m.exitInitializationMode()
    m.enterContinuousTimeMode()
    return m, [d.variable.derivative.name for d in md.derivatives]


def per_call(m, x, n=20000):
    xs, dx = (ctypes.c_double * 18)(*x), (ctypes.c_double * 18)()
    t0 = time.perf_counter()
    for _ in range(n):
        m.setContinuousStates(xs, 18)
        m.getDerivatives(dx, 18)
    return (time.perf_counter() - t0) / n


def main():
    q = delta.inverse_kinematics(RL5, [0.1, -0.2, -1.0])
    hand, horder = instance("DeltaRobot")
    eq, eorder = instance("DeltaRobotEquations")
    x = list(q) + [0.0] * 9
    xe = [x[horder.index(f"{n[5]}[{3 * (int(n[3]) - 1) + int(n[7])}]")] for n in eorder]
    runs = [(per_call(hand, x), per_call(eq, xe)) for _ in range(11)]  # interleaved: the same load for both
    th = statistics.median(h for h, _ in runs)
    te = statistics.median(e for _, e in runs)
    print(f"right-hand side through FMI: hand-written {th * 1e6:.2f} us, equations {te * 1e6:.2f} us, "
          f"ratio {te / th:.2f}")


if __name__ == "__main__":
    main()
