"""CPU time of turning a built FMU into a portable one (``make_portable``): every member
compressed in the build, against the large bundle members (the interpreter's and numpy's shared
libraries) copied compressed from the build cache, in the same run: interleaved rounds, medians,
process CPU seconds (this process and the trace's child), so that a loaded machine changes the
figures less than wall time would. Also checks that both FMUs hold the same members with the same
bytes (the standard library's zip aside: its entries carry the time of the build).

Usage: python benchmarks/portable_build.py [--rounds 3] [model.py ...]   (default: oscillator, delta_robot)
"""
from __future__ import annotations

import argparse
import resource
import statistics
import tempfile
import zipfile
from pathlib import Path

import deltafmi.builder.portable as portable
from deltafmi.builder.packager import build_cached

FMU_SRC = Path(__file__).resolve().parents[1] / "fmu_src"


def _cpu() -> float:
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def _members(fmu: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(fmu) as archive:
        return {name: archive.read(name) for name in archive.namelist() if not name.endswith(".zip")}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs="*", default=["oscillator.py", "delta_robot.py"])
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    cached_from = portable._LARGE_MEMBER
    out = Path(tempfile.mkdtemp(prefix="portable-build-"))
    for model in args.models:
        fmu = build_cached(FMU_SRC / model)
        portable.make_portable(fmu, out / "first.fmu")  # the cache's compressed members, once
        seconds: dict[str, list[float]] = {"every member": [], "large ones cached": []}
        for _ in range(args.rounds):
            for label, threshold in (("every member", 1 << 62), ("large ones cached", cached_from)):
                portable._LARGE_MEMBER = threshold
                before = _cpu()
                portable.make_portable(fmu, out / f"{label}.fmu")
                seconds[label].append(_cpu() - before)
        portable._LARGE_MEMBER = cached_from
        every, cached = (statistics.median(seconds[k]) for k in ("every member", "large ones cached"))
        sizes = [(out / f"{k}.fmu").stat().st_size / 1e6 for k in seconds]
        same = _members(out / "every member.fmu") == _members(out / "large ones cached.fmu")
        print(f"{model}: every member compressed {every:.2f} CPU-s, large members cached {cached:.2f} CPU-s "
              f"(ratio {cached / every:.2f}); zipped {sizes[0]:.2f} / {sizes[1]:.2f} MB; same members: {same}")


if __name__ == "__main__":
    main()
