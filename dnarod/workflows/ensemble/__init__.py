"""Ensembles of runs on dask.distributed: sweeps over forces, turns, salts, sequences and seeds.

A TOML spec (:mod:`dnarod.workflows.ensemble.spec`, keys :mod:`dnarod.workflows.ensemble.schema`) expands into
members with stable ids; each member is a normal run directory (:mod:`dnarod.run`) under the
ensemble folder, run on a dask worker (:mod:`dnarod.workflows.ensemble.cluster`), resumed from its
checkpoint after a lost worker or an interrupted command (:mod:`dnarod.workflows.ensemble.member`), and
reduced on the worker to a row of observables (:mod:`dnarod.workflows.ensemble.reduce`, or a protocol's
own, :mod:`dnarod.workflows.ensemble.protocol`); the rows form one table (:mod:`dnarod.workflows.ensemble.results`).

>>> from dnarod.workflows.ensemble import Ensemble
>>> ens = Ensemble.from_toml("examples/quick_ensemble.toml", "quick_fx").run(workers=0, progress=False)
>>> len(ens.results().to_pylist())   # one row per member (examples/force_extension.toml is the full-size spec)
2
"""
from dnarod.workflows.ensemble.cluster import WORKER_ENV, connect, local_cluster, slurm_cluster
from dnarod.workflows.ensemble.ensemble import Ensemble
from dnarod.workflows.ensemble.member import run_member
from dnarod.workflows.ensemble.protocol import DEFAULT as DEFAULT_PROTOCOL, PROTOCOLS, build_runspec, register_protocol
from dnarod.workflows.ensemble.reduce import reduce_run
from dnarod.workflows.ensemble.schema import Key, SpecError
from dnarod.workflows.ensemble.spec import EnsembleSpec, Member, load_spec, member_id, parse_spec

__all__ = ["Ensemble", "EnsembleSpec", "Member", "Key", "SpecError", "load_spec", "parse_spec", "member_id",
           "run_member", "reduce_run", "build_runspec", "register_protocol", "PROTOCOLS", "DEFAULT_PROTOCOL",
           "local_cluster", "connect", "slurm_cluster", "WORKER_ENV"]
