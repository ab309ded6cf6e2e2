"""deltafmi: Python components as FMI 2.0 FMUs, and a co-simulation master for them.

The public API, importable from here (``from deltafmi import load_scenario, Master``):

* scenarios: :func:`load_scenario` -> :class:`Scenario`, :func:`resolve_system` -> :class:`System`
  (checked against its FMUs), :func:`load_ssp`, :func:`export_ssp`;
* runs: :func:`simulate` -> :class:`Result` (in memory, with units), :class:`Master`
  (``Master(system, result=...).run()``), :func:`read_result` (``.csv``, ``.parquet``, ``.mat``),
  :func:`plot_result`;
* FMUs: :func:`build_fmu`, :func:`build_cached`, :func:`export_fmu` (a scenario as one FMU);
* linear models: :func:`linearize_fmu`, :func:`linearize_scenario`, :class:`LinearModel`;
* studies: :func:`load_study`, :func:`plan_study`, :func:`open_store`, :func:`sweep_study`
  (what ``deltafmi sweep`` runs);
* errors: :class:`DeltaFmiError`, the base of every error deltafmi raises (``except DeltaFmiError``
  catches them all; each carries the command line's ``exit_code``); :class:`ScenarioError`,
  :class:`BadInput`, :class:`SimulationError`, :class:`ResultWriteError`, :class:`Interrupted`
  (runs), :class:`ComponentSourceError`, :class:`BuildError` (builds).

This module imports nothing when imported: each name loads its module on first use (PEP 562). It
is bundled into every FMU's ``resources/`` together with the modules of :mod:`deltafmi.component`
and :mod:`deltafmi.physics` that the FMU's model reaches (``deltafmi.builder.reach``), and must
stay cheap to import inside an embedded interpreter. A component's source imports from
:mod:`deltafmi.component` and :mod:`deltafmi.physics` directly, never these names: an FMU
carries none of their modules (``reach`` follows import statements, not this table).
"""

__version__ = "0.1.0"

#: public name -> the module that defines it
_API = {
    "load_scenario": "deltafmi.master.scenario.spec",
    "Scenario": "deltafmi.master.scenario.spec",
    "resolve_system": "deltafmi.master.scenario.resolve",
    "System": "deltafmi.master.scenario.system",
    "load_ssp": "deltafmi.master.ssp.read",
    "export_ssp": "deltafmi.master.ssp.write",
    "Master": "deltafmi.master.stepping.master",
    "simulate": "deltafmi.master.simulate",
    "Result": "deltafmi.master.results.result",
    "read_result": "deltafmi.master.results.result",
    "plot_result": "deltafmi.master.results.result",
    "build_fmu": "deltafmi.builder.packager",
    "build_cached": "deltafmi.builder.packager",
    "export_fmu": "deltafmi.apps.export_fmu",
    "linearize_fmu": "deltafmi.master.linearize.fmu",
    "linearize_scenario": "deltafmi.master.linearize.closed_loop",
    "LinearModel": "deltafmi.master.linearize.linear_model",
    "load_study": "deltafmi.apps.studies.spec",
    "plan_study": "deltafmi.apps.studies.plan",
    "open_store": "deltafmi.apps.studies.driver",
    "sweep_study": "deltafmi.apps.studies.driver",
    "DeltaFmiError": "deltafmi.runtime.errors",
    "ScenarioError": "deltafmi.errors",
    "BadInput": "deltafmi.errors",
    "SimulationError": "deltafmi.errors",
    "ResultWriteError": "deltafmi.errors",
    "Interrupted": "deltafmi.errors",
    "ComponentSourceError": "deltafmi.builder.source_error",
    "BuildError": "deltafmi.toolchain",
}

__all__ = sorted(_API)

#: imported before any public name is answered: it hands the master the builder as its FMU
#: provider (docs/architecture.md). A name, not a literal: an FMU carries this file, and
#: builder/reach.py follows literal import_module() calls into what it bundles
_COMPOSITION_ROOT = "deltafmi.apps"


def __getattr__(name: str) -> object:
    module = _API.get(name)
    if module is None:
        raise AttributeError(f"module 'deltafmi' has no attribute '{name}'")
    import importlib

    importlib.import_module(_COMPOSITION_ROOT)
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # later lookups skip this function
    return value


def __dir__() -> list:
    return sorted(set(globals()) | set(_API))
