"""Issue 26 item 1: which compiler turns the Python kernels into C functions over C data? Measured.

Every candidate compiles the plant derivative ``state_derivative`` of
deltafmi/physics/delta/dynamics.py (and what it calls) into a C function with one ABI, that of
the hand transcription benchmarks/native/flagship.c::

    int kernel(const DeltaParams *p, double pole, const double x[18], const double u[3],
               const double f[3], double dx[18]);      /* p: the 13 doubles of DeltaParams */

and one C timing loop (compiled here) calls it through the function pointer, as a solver's RHS
callback would, with no Python between calls. Candidates:

- C transcription: benchmarks/native/flagship.c (the reference of speed);
- codegen: deltafmi/builder/codegen, our translator over the kernels' AST (unchanged source);
- Cython 3, pure-Python mode: the kernel functions' unchanged source in a module with an
  augmenting .pxd (C signatures, ctuples, ``noexcept nogil``) and a C entry written for it
  (``cdef api``; its address from the module's ``__pyx_capi__`` capsule);
- numba: ``@cfunc`` over ``njit`` copies of the unchanged functions (their globals rebound to the
  jitted copies), same C entry as Cython's, in the running process (JIT);
(The compiler of whole Python modules into CPython extensions that FMUs shipped when this was
measured, Python objects in and out, went when the code generator became the one compiler.)

Each candidate's numbers are compared with the Python source (``state_derivative`` run by the
interpreter) on the flagship's plant state at a few instants (bit for bit, else the largest
relative difference). Times: ns per call, the median over instants and rounds of C-loop bursts;
ratios against the C transcription measured in the same round. A candidate whose package is
missing is skipped with the reason.

The generated controller, path and closed loop against the hand C (issue 26 item 2):
benchmarks/kernel_codegen_flagship.py.

Usage: python benchmarks/kernel_compilers.py [--repeats 5] [--calls 20000]
"""
from __future__ import annotations

import argparse
import ctypes
import importlib
import importlib.util
import inspect
import shutil
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
import types
from ctypes import POINTER, c_double, c_int, c_long, c_void_p
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

import native  # noqa: E402  (benchmarks/native.py: the C transcription and the flagship's data)
from deltafmi.builder.codegen import Entry, Obj, Vec, generate  # noqa: E402
from deltafmi.builder.codegen import D  # noqa: E402

from deltafmi.physics.delta import dynamics  # noqa: E402
from deltafmi.physics.delta.params import DeltaParams  # noqa: E402

_D = POINTER(c_double)
#: -ffp-contract=off: no fused multiply-add; -fno-builtin-pow: pow(x, 2.0) stays libm's pow, as in
#: Python (GCC would fold it to x * x, which can differ in the last bit)
CFLAGS = ["-std=c99", "-O2", "-ffp-contract=off", "-fno-builtin-pow"]

DRIVER = r"""
#define _POSIX_C_SOURCE 199309L
#include <time.h>
typedef int (*kernel_fn)(const double *, double, const double *, const double *, const double *, double *);

/* ns per call of `calls` calls of the kernel at one point, looped here */
double kernel_ns(void *fn, const double *p, double pole, const double *x, const double *u,
                 const double *f, long calls)
{
    kernel_fn k = (kernel_fn)fn;
    const double *volatile xp = x;
    double dx[18];
    volatile double check = 0.0;
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (long i = 0; i < calls; i++) {
        k(p, pole, xp, u, f, dx);
        check += dx[17];
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    return ((t1.tv_sec - t0.tv_sec) * 1e9 + (t1.tv_nsec - t0.tv_nsec)) / calls;
}

int kernel_call(void *fn, const double *p, double pole, const double *x, const double *u,
                const double *f, double *dx)
{
    return ((kernel_fn)fn)(p, pole, x, u, f, dx);
}
"""


class Skip(Exception):
    """A candidate that cannot be built here; the message says why."""


@dataclass
class Candidate:
    """One compiled kernel: its C function's address."""

    name: str
    address: int
    build_s: float = 0.0
    size: str = ""
    facts: dict = field(default_factory=dict)
    keep: list = field(default_factory=list)


def cc() -> list[str]:
    from deltafmi.toolchain import require_compiler

    return require_compiler(HERE / "kernel_compilers.py")


def compile_so(source: Path, out: Path, extra: tuple = ()) -> Path:
    done = subprocess.run([*cc(), *CFLAGS, "-shared", "-fPIC", str(source), *extra, "-o", str(out), "-lm"],
                          capture_output=True, text=True)
    if done.returncode:
        raise RuntimeError(f"compiling {source} failed:\n{done.stderr[-3000:]}")
    return out


def stripped_size(path: Path, scratch: Path) -> int:
    copy = scratch / ("stripped-" + path.name)
    shutil.copy2(path, copy)
    subprocess.run(["strip", "--strip-unneeded", str(copy)], capture_output=True)
    return copy.stat().st_size


def kib(n: int) -> str:
    return f"{n / 1024:.0f} KiB"


# --- candidates -----------------------------------------------------------------------------------
def hand_c(tmp: Path) -> Candidate:
    begin = time.perf_counter()
    lib_path = native.compile_baseline(tmp)
    build = time.perf_counter() - begin
    lib = ctypes.CDLL(str(lib_path))
    address = ctypes.cast(lib.flagship_state_derivative, c_void_p).value
    return Candidate("C transcription (hand, flagship.c)", address, build_s=build,
                     size=kib(stripped_size(lib_path, tmp)) + " (whole flagship)", keep=[lib],
                     facts={"gil": "yes", "portable": "yes", "install": "C compiler"})


CODEGEN_ADAPTER = """
int kernel_abi(const DeltaParams *p, double pole, const double *x, const double *u, const double *f,
               double *dx)
{
    return dfk_state_derivative(p, x, u, f, pole, dx);
}
"""


def codegen_source() -> str:
    """dynamics.state_derivative as C (deltafmi/builder/codegen)."""
    entry = Entry("dfk_state_derivative", dynamics.state_derivative, [Obj(DeltaParams), Vec(18), Vec(3), Vec(3), D])
    # _as_list converts a numpy array or sequence to a list: fixed-length C arrays need none
    return generate([entry], identities={"_as_list"})


def codegen(tmp: Path) -> Candidate:
    begin = time.perf_counter()
    source = tmp / "codegen_dynamics.c"
    source.write_text(codegen_source() + CODEGEN_ADAPTER)
    generated = time.perf_counter() - begin
    lib_path = compile_so(source, tmp / "codegen_dynamics.so")
    build = time.perf_counter() - begin
    lib = ctypes.CDLL(str(lib_path))
    lines = len(source.read_text().splitlines())
    return Candidate("codegen (ours, over the AST)", ctypes.cast(lib.kernel_abi, c_void_p).value, build_s=build,
                     size=kib(stripped_size(lib_path, tmp)), keep=[lib],
                     facts={"gil": "yes", "portable": "yes", "install": "C compiler",
                            "note": f"generation {1e3 * generated:.0f} ms, {lines} lines of C"})


#: the kernel functions Cython and numba compile from dynamics.py's unchanged source
KERNELS = ("_arm_mass_inverse", "_arm_response", "_arm", "_sym3_inv", "_schur_factor", "_schur_solve")

CYTHON_PXD = """\
# C signatures for the unchanged kernel source (Cython's augmenting .pxd, pure-Python mode).
# The source's `import math` is shadowed by C's libm; tuple-valued locals need declaring (the
# float ones are inferred with infer_types=True).
cimport cython
from libc cimport math
ctypedef (double, double, double) cF3
ctypedef (double, double, double, double, double) cF5
ctypedef (double, double, double, double, double, double) cF6
ctypedef (double, double, double, double, double, double, double, double, double) cF9
ctypedef (double, double, double, double, double, double, double, double, double, double, double,
          double, double, double, double, double, double, double, double, double, double) cF21

ctypedef (cF3, cF6, cF3, cF9, cF3, cF3, double) cArm

cdef inline cF9 _arm_mass_inverse(double a, double b, double beta, double s1, double c1, double s2, double c2,
                           double s3, double c3) noexcept nogil
@cython.locals(W=cF6)
cdef inline (cF6, cF9) _arm_response(double i11, double i12, double i13, double i22, double i23, double i33,
                              double h00, double h01, double h02, double h10, double h11, double h12,
                              double h20, double h21, double h22) noexcept nogil
@cython.locals(bb=cF3, W=cF6, Y=cF9)
cdef inline cArm _arm(cF5 consts, double damping, double pole, double cr, double sr, double l0l3, double l1,
               double l2, double q1, double q2, double q3, double v1, double v2, double v3, double u,
               double fx, double fy, double fz) noexcept nogil
cdef inline cF6 _sym3_inv(double a11, double a12, double a13, double a22, double a23, double a33) noexcept nogil
cdef inline cF21 _schur_factor(cF6 W1, cF6 W2, cF6 W3) noexcept nogil
cdef inline cF6 _schur_solve(cF21 factors, cF6 r) noexcept nogil
@cython.locals(consts=cF5, arm1=cArm, arm2=cArm, arm3=cArm, lam=cF6, k=int)
cdef api int c_state_derivative(const double *p, double pole, const double *x, const double *u,
                                const double *f, double *dx) noexcept nogil
"""

#: the C entry over C data that Cython and numba need written: dynamics._evaluate /
#: state_derivative / _constants / _subtract_response (lists, the parameter object) transcribed
#: onto double pointers, same operations in the same order
ENTRY = """\
def c_state_derivative(p, pole, x, u, f, dx):
    mpa = (p[9] + p[10]) / 3.0
    consts = (p[6] + p[7] + (p[8] + mpa) * p[1] * p[1], (0.5 * p[8] + mpa) * p[1] * p[2],
              (p[8] / 3.0 + mpa) * p[2] * p[2], p[11] * (p[4] * p[5] + (p[8] + mpa) * p[1]),
              p[11] * (0.5 * p[8] + mpa) * p[2])
    l0l3, l1, l2, dmp = p[0] - p[3], p[1], p[2], p[12]
    arm1 = _arm(consts, dmp, pole, 1.0, 0.0, l0l3, l1, l2, x[0], x[1], x[2], x[9], x[10], x[11],
                u[0], f[0], f[1], f[2])
    arm2 = _arm(consts, dmp, pole, -0.5, 0.8660254037844386, l0l3, l1, l2, x[3], x[4], x[5], x[12],
                x[13], x[14], u[1], f[0], f[1], f[2])
    arm3 = _arm(consts, dmp, pole, -0.5, -0.8660254037844386, l0l3, l1, l2, x[6], x[7], x[8], x[15],
                x[16], x[17], u[2], f[0], f[1], f[2])
    b1, W1, x1, Y1 = arm1[0], arm1[1], arm1[2], arm1[3]
    b2, W2, x2, Y2 = arm2[0], arm2[1], arm2[2], arm2[3]
    b3, W3, x3, Y3 = arm3[0], arm3[1], arm3[2], arm3[3]
    lam = _schur_solve(_schur_factor(W1, W2, W3), (b2[0] - b1[0], b2[1] - b1[1], b2[2] - b1[2],
                                                   b3[0] - b1[0], b3[1] - b1[1], b3[2] - b1[2]))
    la0, la1, la2, lb0, lb1, lb2 = -lam[0], -lam[1], -lam[2], -lam[3], -lam[4], -lam[5]
    F0, F1, F2 = la0 + lb0, la1 + lb1, la2 + lb2
    for k in range(9):
        dx[k] = x[9 + k]
    dx[9] = x1[0] - (Y1[0] * F0 + Y1[1] * F1 + Y1[2] * F2)
    dx[10] = x1[1] - (Y1[3] * F0 + Y1[4] * F1 + Y1[5] * F2)
    dx[11] = x1[2] - (Y1[6] * F0 + Y1[7] * F1 + Y1[8] * F2)
    dx[12] = x2[0] + (Y2[0] * la0 + Y2[1] * la1 + Y2[2] * la2)
    dx[13] = x2[1] + (Y2[3] * la0 + Y2[4] * la1 + Y2[5] * la2)
    dx[14] = x2[2] + (Y2[6] * la0 + Y2[7] * la1 + Y2[8] * la2)
    dx[15] = x3[0] + (Y3[0] * lb0 + Y3[1] * lb1 + Y3[2] * lb2)
    dx[16] = x3[1] + (Y3[3] * lb0 + Y3[4] * lb1 + Y3[5] * lb2)
    dx[17] = x3[2] + (Y3[6] * lb0 + Y3[7] * lb1 + Y3[8] * lb2)
    return 0
"""


def kernel_source() -> str:
    """The KERNELS' unchanged source from dynamics.py, with the names they need."""
    body = "\n\n".join(inspect.getsource(getattr(dynamics, name)) for name in KERNELS)
    return "import math\n\n" + body


def cython(tmp: Path) -> Candidate:
    try:
        import Cython
    except ImportError:
        raise Skip("Cython is not installed (pip install cython)") from None
    work = tmp / "cython"
    work.mkdir()
    (work / "dyn_cy.py").write_text(kernel_source() + "\n\n" + ENTRY)
    (work / "dyn_cy.pxd").write_text(CYTHON_PXD)
    (work / "setup.py").write_text(textwrap.dedent(f"""\
        from setuptools import setup, Extension
        from Cython.Build import cythonize
        setup(ext_modules=cythonize([Extension("dyn_cy", ["dyn_cy.py"], extra_compile_args={CFLAGS[1:]!r})],
                                    compiler_directives={{"language_level": 3, "infer_types": True}}, quiet=True))
        """))
    begin = time.perf_counter()
    done = subprocess.run([sys.executable, "setup.py", "build_ext", "--inplace"], cwd=work, capture_output=True,
                          text=True)
    build = time.perf_counter() - begin
    if done.returncode:
        raise Skip(f"Cython {Cython.__version__} failed: {(done.stdout + done.stderr)[-600:]}")
    built = next(work.glob("dyn_cy*.so"))
    spec = importlib.util.spec_from_file_location("dyn_cy", built)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    capsule = module.__pyx_capi__["c_state_derivative"]
    get = ctypes.pythonapi.PyCapsule_GetPointer
    get.restype, get.argtypes = c_void_p, [ctypes.py_object, ctypes.c_char_p]
    name = ctypes.pythonapi.PyCapsule_GetName
    name.restype, name.argtypes = ctypes.c_char_p, [ctypes.py_object]
    address = get(capsule, name(capsule))
    return Candidate(f"Cython {Cython.__version__} (pure-Python mode + .pxd)", address, build_s=build,
                     size=kib(stripped_size(built, tmp)), keep=[module],
                     facts={"gil": "yes", "portable": portable(built, tmp), "install": "cython (build); C compiler",
                            "note": "C entry written by hand; unchanged kernel bodies"})


def numba_cfunc(tmp: Path) -> Candidate:
    try:
        import numba
        from numba import types as nt
    except ImportError:
        raise Skip("numba is not installed (pip install numba)") from None
    begin = time.perf_counter()
    jitted: dict = {}
    namespace = dict(vars(dynamics), **{"__builtins__": __builtins__})
    for name in KERNELS:  # the unchanged functions, their globals rebound to the jitted copies
        f = getattr(dynamics, name)
        jitted[name] = numba.njit(types.FunctionType(f.__code__, namespace, name, f.__defaults__))
    namespace.update(jitted)
    entry_ns = dict(jitted, math=__import__("math"))
    exec(ENTRY, entry_ns)
    sig = nt.int32(nt.CPointer(nt.float64), nt.float64, nt.CPointer(nt.float64), nt.CPointer(nt.float64),
                   nt.CPointer(nt.float64), nt.CPointer(nt.float64))
    compiled = numba.cfunc(sig, nopython=True)(entry_ns["c_state_derivative"])
    build = time.perf_counter() - begin
    import llvmlite
    site = Path(numba.__file__).parent.parent
    runtime = sum(f.stat().st_size for d in ("numba", "llvmlite") for f in (site / d).rglob("*") if f.is_file())
    return Candidate(f"numba {numba.__version__} @cfunc (JIT)", compiled.address, build_s=build,
                     size=f"0 in the FMU; host needs numba+llvmlite {runtime / 2**20:.0f} MiB",
                     keep=[compiled],
                     facts={"gil": "yes", "portable": "no (LLVM JIT in the host's Python)",
                            "install": f"numba + llvmlite {llvmlite.__version__} at run time",
                            "note": f"JIT {build:.1f} s at every process start (less with cache=True, a disk cache)"})


PROBE = """\
import math


def probe(x: float, y: float) -> float:
    s = math.sin(x) * y
    norm = math.sqrt(sum(tuple(t * t for t in (s, x, y))))  # a generator made a tuple: outside the subsets
    return s + norm
"""


def unsupported_errors(tmp: Path) -> dict[str, str]:
    """What each compiler says about a kernel with a construct outside its subset (PROBE, line 6,
    a generator expression turned into a tuple): the first line of its message."""
    work = tmp / "probe"
    work.mkdir()
    (work / "probe_kernel.py").write_text(PROBE)
    spec = importlib.util.spec_from_file_location("probe_kernel", work / "probe_kernel.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    said = {}
    try:
        generate([Entry("probe", module.probe, [D, D])])
        said["codegen"] = "compiled (no error)"
    except Exception as exc:  # noqa: BLE001 (reporting what the tool raised)
        said["codegen"] = str(exc).replace(str(work) + "/", "")
    try:
        (work / "probe_kernel.pxd").write_text("from libc cimport math\n"
                                               "cdef double probe(double x, double y) noexcept nogil\n")
        done = subprocess.run([sys.executable, "-m", "cython", "-3", "probe_kernel.py"], cwd=work,
                              capture_output=True, text=True)
        lines = [ln for ln in (done.stdout + done.stderr).splitlines() if ln.startswith("probe_kernel.py:")]
        if lines:
            said["Cython"] = f"{len(lines)} errors, e.g. " + sorted(lines, key=lambda ln: ln.split(":")[1])[-1]
        elif done.returncode:
            said["Cython"] = "not run: " + (done.stdout + done.stderr).strip().splitlines()[-1]
        else:
            said["Cython"] = "compiled (no error)"
    except OSError as exc:
        said["Cython"] = f"not run: {exc}"
    try:
        import numba
        from numba import types as nt

        try:
            numba.cfunc(nt.float64(nt.float64, nt.float64))(module.probe)
            said["numba"] = "compiled (no error)"
        except Exception as exc:  # noqa: BLE001
            text = str(exc).splitlines()
            line = next((ln.strip().rpartition(",")[2].strip(" :") for ln in text
                         if ln.strip().startswith("File ")), "")
            said["numba"] = f"{type(exc).__name__}: {text[1] if len(text) > 1 else text[0]} (probe_kernel.py, {line})"
    except ImportError:
        said["numba"] = "not installed"
    return said


def portable(library: Path, tmp: Path) -> str:
    """Can a C process with no Python load ``library``? (dlopen RTLD_NOW, as an FMU's binary would)."""
    probe = tmp / "dlopen_probe.c"
    probe.write_text('#include <dlfcn.h>\n#include <stdio.h>\nint main(int c, char **v) {\n'
                     '    if (!dlopen(v[1], RTLD_NOW)) { printf("%s\\n", dlerror()); return 1; }\n    return 0;\n}\n')
    exe = tmp / "dlopen_probe"
    subprocess.run([*cc(), str(probe), "-o", str(exe), "-ldl"], check=True, capture_output=True)
    done = subprocess.run([str(exe), str(library)], capture_output=True, text=True)
    if done.returncode == 0:
        return "yes"
    missing = done.stdout.strip().rpartition(":")[2].strip()
    return f"no (dlopen: {missing[:40]})"


# --- the measurement -----------------------------------------------------------------------------
def flagship_points(baseline: native.Baseline, spec) -> list[tuple[np.ndarray, np.ndarray]]:
    """(x, u) at a few instants of the flagship's closed loop (the state and the torque held next)."""
    steps = 3500
    rows, states, _ = baseline.run(spec, steps)
    instants = sorted({0, *(int(round(f * steps)) for f in (0.1, 0.2, 0.4, 0.6, 0.8))})
    return [(np.ascontiguousarray(states[k]), np.ascontiguousarray(rows[min(k + 1, steps), 10:13]))
            for k in instants]


def reference(spec, x: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The Python source's state derivative (the interpreter running dynamics.py)."""
    p = DeltaParams(**{n: getattr(spec.plant, n) for n in native.ROBOT})
    return np.array(dynamics.state_derivative(p, x.tolist(), u.tolist(), list(spec.f), spec.pole))


def agreement(got: list[np.ndarray], want: list[np.ndarray]) -> str:
    if all(np.array_equal(a, b) for a, b in zip(got, want)):
        return "bit for bit"
    rel = max(float(np.max(np.abs(a - b) / np.maximum(np.abs(b), 1e-300))) for a, b in zip(got, want))
    return f"max rel {rel:.1e}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="rounds; figures are medians over them")
    parser.add_argument("--calls", type=int, default=20000, help="calls per C-loop burst")
    parser.add_argument("--coverage", action="store_true",
                        help="only list which functions of the robot's kernel modules the codegen "
                             "translates from their annotations, and why the others fail")
    args = parser.parse_args()
    if args.coverage:
        coverage()
        return
    with tempfile.TemporaryDirectory(prefix="deltafmi-kc-") as scratch:
        run(Path(scratch), args.repeats, args.calls)


def run(tmp: Path, repeats: int, calls: int) -> None:
    driver = ctypes.CDLL(str(compile_so(_write(tmp / "driver.c", DRIVER), tmp / "driver.so")))
    driver.kernel_ns.restype = c_double
    driver.kernel_ns.argtypes = [c_void_p, _D, c_double, _D, _D, _D, c_long]
    driver.kernel_call.restype = c_int
    driver.kernel_call.argtypes = [c_void_p, _D, c_double, _D, _D, _D, _D]
    baseline = native.Baseline(native.compile_baseline(tmp))
    spec = native.flagship_spec(native.load_flagship())
    points = flagship_points(baseline, spec)
    want = [reference(spec, x, u) for x, u in points]
    p = np.array([getattr(spec.plant, n) for n in native.ROBOT])
    f = np.array(list(spec.f))
    ptr = lambda a: a.ctypes.data_as(_D)  # noqa: E731

    candidates: list[Candidate] = []
    for build in (hand_c, codegen, cython, numba_cfunc):
        try:
            candidates.append(build(tmp))
        except Skip as why:
            print(f"skipped {build.__name__}: {why}")
    for c in candidates:
        got = []
        for x, u in points:
            dx = np.empty(18)
            driver.kernel_call(c.address, ptr(p), spec.pole, ptr(x), ptr(u), ptr(f), ptr(dx))
            got.append(dx)
        c.facts["numbers"] = agreement(got, want)

    times: dict[str, list[float]] = {c.name: [] for c in candidates}
    ratios: dict[str, list[float]] = {c.name: [] for c in candidates}
    python_ns: list[float] = []
    for _ in range(repeats):
        round_ns = {}
        for c in candidates:
            per = []
            for x, u in points:
                per.append(driver.kernel_ns(c.address, ptr(p), spec.pole, ptr(x), ptr(u), ptr(f), calls))
            round_ns[c.name] = statistics.median(per)
            times[c.name].append(round_ns[c.name])
        base = round_ns[candidates[0].name]
        for c in candidates:
            ratios[c.name].append(round_ns[c.name] / base)
        params = DeltaParams(**{n: getattr(spec.plant, n) for n in native.ROBOT})
        xl, ul, fl = points[0][0].tolist(), points[0][1].tolist(), f.tolist()
        begin = time.perf_counter()
        for _ in range(1000):
            dynamics.state_derivative(params, xl, ul, fl, spec.pole)
        python_ns.append(1e6 * (time.perf_counter() - begin))

    print(f"plant derivative (dynamics.state_derivative) on the flagship's state at {len(points)} instants; "
          f"{repeats} rounds, C-loop bursts of {calls} calls; numbers against the Python source run by the "
          f"interpreter ({statistics.median(python_ns):.0f} ns per call)")
    head = (f"{'candidate':46s} {'ns/call':>8s} {'x C':>6s}  {'numbers':13s} {'build s':>7s}  {'no GIL':6s} "
            f"{'portable':10s}")
    print(head)
    for c in candidates:
        med = statistics.median(times[c.name])
        print(f"{c.name:46s} {med:8.0f} {statistics.median(ratios[c.name]):6.2f}  {c.facts['numbers']:13s} "
              f"{c.build_s:7.1f}  {c.facts['gil']:6s} {c.facts['portable']}")
    print("a kernel with a construct outside the subset (a generator expression at line 6):")
    for tool, message in unsupported_errors(tmp).items():
        print(f"  {tool}: {message}")
    print("size in the FMU, what a user installs, notes:")
    for c in candidates:
        note = f"; {c.facts['note']}" if "note" in c.facts else ""
        print(f"  {c.name}: {c.size}; {c.facts['install']}{note}")


def coverage() -> None:
    """The codegen prototype over every function of the robot's kernel modules, typed from its
    annotations alone (kernel_codegen.signature_of): what translates, the first error of the rest."""
    from deltafmi.builder.codegen import CodegenError, signature_of

    modules = [importlib.import_module(f"deltafmi.physics.delta.{name}")
               for name in ("dynamics", "kinematics", "jacobian", "control_law", "trajectory")]
    done = []
    for module in modules:
        for name, func in vars(module).items():
            if not inspect.isfunction(func) or func.__module__ != module.__name__:
                continue
            label = f"{module.__name__.rpartition('.')[2]}.{name}"
            try:
                generate([Entry("k", func, signature_of(func))], identities={"_as_list"})
                done.append(label)
            except CodegenError as exc:
                print(f"  {label}: {str(exc).replace(str(ROOT) + '/', '')}")
    print(f"translated from annotations alone ({len(done)}): {', '.join(done)}")


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


if __name__ == "__main__":
    main()
