"""The OpenMM engine (docs/formulation.md §7).

Each base pair is a rigid body carried by three particles of mass ``m/3`` on an equilateral
triangle of circumradius ``l = sqrt(J3/m)`` in its d1-d2 plane, held by constraints: node
inertia ``J = m l^2 (1/2, 1/2, 1)`` about (d1, d2, d3) (dna-default: 650 amu, l = 0.6 nm,
(117, 117, 234) amu nm^2). Angular velocities are body-frame (components on d1, d2, d3).

Modules: :mod:`.particles` (node <-> particle maps), :mod:`.forces` (step energy: portable
CustomCompoundBondForce and fast numba/PythonForce path), :mod:`.nonbonded` (WCA +
Debye-Hueckel), :mod:`.loads` (external loads), :mod:`.system` (System from a RodModel),
:mod:`.simulation` (the engine: advance, node state, energies, checkpoints), :mod:`dnarod.structure.export`
(PDB/DCD/XTC for mdtraj and MDAnalysis). Runs with reporters, checkpoints and resume are the
run layer's (:mod:`dnarod.run`, ``dnarod simulate``).

Example (20 bp pulled by its last node, 200 steps, a frame every 10 steps; a real run takes more of both):

>>> from dnarod.core.forcefield import load_forcefield
>>> from dnarod.engines.openmm import RodSimulation
>>> from dnarod.physics.loads import PullingForce
>>> from dnarod.run import run_engine, DtrajReporter
>>> model = load_forcefield("dna-default").model_from_sequence("ACGT" * 5)
>>> sim = RodSimulation.create(model, temperature=300, loads=[PullingForce(-1, [0, 0, 3.0])], seed=1)
>>> rep = DtrajReporter("run1.dtraj", model.n_nodes, interval=10)
>>> _ = run_engine(sim, 200, [rep], checkpoint="run1.npz", checkpoint_interval=100)
>>> rep.close()
"""
_EXPORTS = {"RodSimulation": "simulation", "build_system": "system"}
__all__ = list(_EXPORTS)


def __getattr__(name):
    # Lazy: importing dnarod.engines.openmm (e.g. for the CLI) does not load OpenMM and numba until used.
    if name in _EXPORTS:
        import importlib

        return getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
