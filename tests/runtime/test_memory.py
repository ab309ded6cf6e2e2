"""Resident memory stays flat over thousands of fmi2Reset and instantiate/free cycles.

Studies reset FMUs thousands of times. Each cycle of a Co-Simulation FMU with states used to leak
the SUNDIALS objects of its solver (about 1.8 KB per cycle for the Oscillator, 5 KB for the
DeltaRobot); each instantiate/free through fmpy, which unloads the binary in freeInstance, ran the
boot code and imported the model anew (about 290 KB per cycle). Each case runs in a fresh process.
fmpy's own cost of a load/unload (a new FMU2Slave, dlopen, dlclose: about 300 bytes per cycle
here) is measured in the same process and subtracted, so the figure is what the FMU adds.
"""
from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

CYCLES = 3000
#: bytes per cycle we accept: allocator noise is tens of bytes, the old leak 1800 to 5000
LIMIT = 200

SCRIPT = textwrap.dedent("""
    import gc
    import inspect
    import sys
    import fmpy
    from fmpy.fmi2 import FMU2Slave

    # fmpy asks inspect for the signature of each of its fmi2 methods at every load, 3 of the 5 ms
    # a load takes here: the same for every instance of the class, so found once per function. Only
    # fmpy's Python side, in the cycles and in their load-only baseline alike; what the FMU does and
    # keeps at each cycle is the same.
    signature, signatures = inspect.signature, {}

    def kept_signature(method):
        function = getattr(method, "__func__", method)
        if function not in signatures:
            signatures[function] = signature(method)
        return signatures[function]

    inspect.signature = kept_signature

    fmu, how, cycles = sys.argv[1], sys.argv[2], int(sys.argv[3])
    md = fmpy.read_model_description(fmu)
    directory = fmpy.extract(fmu)

    def rss():
        gc.collect()  # garbage waiting for the cycle collector is not a leak
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * 4096

    def new():
        s = FMU2Slave(guid=md.guid, unzipDirectory=directory,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="m")
        s.instantiate()
        return s

    slave = new()

    def cycle():
        global slave
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        for k in range(3):
            slave.doStep(k * 1e-3, 1e-3)
        if how == "reset":
            slave.reset()
        else:
            slave.terminate()
            slave.freeInstance()  # fmpy also unloads the binary here: the next one loads it anew
            slave = new()

    def load_only():  # fmpy's part of a free cycle: no instance
        FMU2Slave(guid=md.guid, unzipDirectory=directory, modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="m").freeLibrary()

    def growth(function):
        for _ in range(300):  # warm up: caches, allocator pools
            function()
        before = rss()
        # what lives now (the modules, fmpy, numpy) is no garbage of the cycles: the collections
        # below skip it and go through what the cycles make, in a millisecond instead of fifty
        gc.freeze()
        for k in range(cycles):
            function()
            if k % 50 == 0:
                gc.collect()  # keep uncollected garbage from raising the high-water mark
        return (rss() - before) / cycles

    print(growth(cycle) - (growth(load_only) if how == "free" else 0.0))
""")


@pytest.mark.parametrize("source", ["oscillator.py", "delta_robot.py"])
@pytest.mark.parametrize("how", ["reset", "free"])
def test_resident_memory_is_flat_over_many_cycles(source, how, build_fmu_from_src):
    fmu = build_fmu_from_src(source)
    out = subprocess.run([sys.executable, "-c", SCRIPT, str(fmu), how, str(CYCLES)],
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    per_cycle = float(out.stdout.strip())
    assert per_cycle < LIMIT, f"{per_cycle:.0f} bytes per {how} cycle"
