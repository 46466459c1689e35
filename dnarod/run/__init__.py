"""The run layer: one engine-neutral way to run, report, checkpoint and resume a simulation.

Example (200 bp for 0.01 ns on the Lax-form engine, into the folder ``run1``):

>>> from dnarod.run import RunSpec, run
>>> result = run(RunSpec(source="ACGT" * 50, engine="lax", time_ns=0.01, excluded_volume=False,
...                      electrostatics=False), "run1", progress=False)
>>> result.files["trajectory"].name, result.summary["engine"]
('trajectory.dtraj', 'lax')

Modules: :mod:`.spec` (:class:`RunSpec`, fingerprint), :mod:`.engine` (engine protocol, Lax-form
adapter, checkpoint files), :mod:`.reporters` (``.dtraj``, energies CSV, progress), :mod:`.loop`
(:func:`run_engine`, the one run loop), :mod:`.api` (:func:`run`, :class:`RunResult`).
"""
from dnarod.run.api import RUN_FILES, RunResult, run
from dnarod.run.engine import Engine
from dnarod.run.loop import run_engine, simulate_engine
from dnarod.run.reporters import ENERGY_COLUMNS, DtrajReporter, EnergyReporter, ProgressReporter, load_energies
from dnarod.run.spec import RunSpec

__all__ = ["RunSpec", "run", "RunResult", "RUN_FILES", "run_engine", "simulate_engine", "Engine", "DtrajReporter",
           "EnergyReporter", "ProgressReporter", "ENERGY_COLUMNS", "load_energies"]
