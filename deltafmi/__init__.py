"""deltafmi: Python components as FMI 2.0 FMUs, and a co-simulation master for them.

The public API, importable from here (``from deltafmi import load_scenario, Master``):

* scenarios: :func:`load_scenario` -> :class:`Scenario`, :func:`resolve_system` -> :class:`System`
  (checked against its FMUs), :func:`load_ssp`, :func:`export_ssp`;
* runs: :func:`simulate` -> :class:`Result` (in memory, with units), :class:`Master`
  (``Master(system, result=...).run()``), :func:`read_result` (``.csv``, ``.parquet``, ``.mat``),
  :func:`plot_result`;
* FMUs: :func:`build_fmu`, :func:`build_cached`;
* linear models: :func:`linearize_fmu`, :func:`linearize_scenario`, :class:`LinearModel`;
* studies: :func:`load_study`, :func:`plan_study`, :func:`open_store`, :func:`sweep_study`
  (what ``deltafmi sweep`` runs);
* errors: :class:`DeltaFmiError`, the base of every error deltafmi raises (``except DeltaFmiError``
  catches them all; each carries the command line's ``exit_code``); :class:`ScenarioError`,
  :class:`BadInput`, :class:`SimulationError`, :class:`ResultWriteError`, :class:`Interrupted`
  (runs), :class:`ComponentSourceError`, :class:`BuildError` (builds).

This module imports nothing when imported: each name loads its module on first use (PEP 562). It
is bundled into every FMU's ``resources/`` together with the modules of :mod:`deltafmi.component`
and :mod:`deltafmi.mechanics` that the FMU's model reaches (``deltafmi.export.reach``), and must
stay cheap to import inside an embedded interpreter. A component's source imports from
:mod:`deltafmi.component` and :mod:`deltafmi.mechanics` directly, never these names: an FMU
carries none of their modules (``reach`` follows import statements, not this table).
"""

__version__ = "0.1.0"

#: public name -> the module that defines it
_API = {
    "load_scenario": "deltafmi.cosim.scenario.spec",
    "Scenario": "deltafmi.cosim.scenario.spec",
    "resolve_system": "deltafmi.cosim.scenario.resolve",
    "System": "deltafmi.cosim.scenario.resolve",
    "load_ssp": "deltafmi.cosim.ssp.read",
    "export_ssp": "deltafmi.cosim.ssp.write",
    "Master": "deltafmi.cosim.stepping.master",
    "simulate": "deltafmi.cosim.simulate",
    "Result": "deltafmi.cosim.results.result",
    "read_result": "deltafmi.cosim.results.result",
    "plot_result": "deltafmi.cosim.results.plot",
    "build_fmu": "deltafmi.export.packager",
    "build_cached": "deltafmi.export.packager",
    "linearize_fmu": "deltafmi.cosim.linearize.fmu",
    "linearize_scenario": "deltafmi.cosim.linearize.closed_loop",
    "LinearModel": "deltafmi.cosim.linearize.linear_model",
    "load_study": "deltafmi.study.spec",
    "plan_study": "deltafmi.study.plan",
    "open_store": "deltafmi.study.driver",
    "sweep_study": "deltafmi.study.driver",
    "DeltaFmiError": "deltafmi.errors",
    "ScenarioError": "deltafmi.errors",
    "BadInput": "deltafmi.errors",
    "SimulationError": "deltafmi.errors",
    "ResultWriteError": "deltafmi.errors",
    "Interrupted": "deltafmi.errors",
    "ComponentSourceError": "deltafmi.export.sources",
    "BuildError": "deltafmi.export.compiler",
}

__all__ = sorted(_API)


def __getattr__(name: str) -> object:
    module = _API.get(name)
    if module is None:
        raise AttributeError(f"module 'deltafmi' has no attribute '{name}'")
    import importlib

    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # later lookups skip this function
    return value


def __dir__() -> list:
    return sorted(set(globals()) | set(_API))
