"""An FMU's own deltafmi runtime is swapped into sys.modules while its model is imported: only the
modules it carries, so that the host's other deltafmi modules stay visible to the host's other
threads meanwhile (a Dask worker unpickling tasks while an FMU starts in its executor)."""
from __future__ import annotations

import sys
from pathlib import Path

import deltafmi.apps.studies.worker  # noqa: F401  (a host module the FMU does not carry)
from conftest import unzip
from deltafmi.runtime import boot


def test_an_active_bundle_swaps_only_what_the_fmu_carries(build_fmu_from_src, tmp_path):
    python_dir = unzip(build_fmu_from_src("oscillator.py"), tmp_path / "osc") / "resources" / "python"
    bundle = boot._Bundle(str(python_dir))
    assert {"deltafmi", "deltafmi.component", "deltafmi.runtime.instance"} <= bundle.names
    assert "deltafmi.apps.studies.worker" not in bundle.names and "deltafmi.builder.packager" not in bundle.names
    host_worker = sys.modules["deltafmi.apps.studies.worker"]
    host_runtime = sys.modules["deltafmi.runtime"]
    with bundle.active():
        import deltafmi.runtime.instance  # noqa: F401  (the FMU's copy, as the boot imports it)
        assert Path(sys.modules["deltafmi.runtime"].__file__).is_relative_to(python_dir)
        assert sys.modules["deltafmi.apps.studies.worker"] is host_worker  # still there for other threads
    assert sys.modules["deltafmi.runtime"] is host_runtime
    assert sys.modules["deltafmi.apps.studies.worker"] is host_worker
