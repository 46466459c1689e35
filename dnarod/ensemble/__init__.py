"""Ensembles of runs on dask.distributed: sweeps over forces, turns, salts, sequences and seeds.

A TOML spec (:mod:`dnarod.ensemble.spec`, keys :mod:`dnarod.ensemble.schema`) expands into
members with stable ids; each member is a normal run directory (:mod:`dnarod.run`) under the
ensemble folder, run on a dask worker (:mod:`dnarod.ensemble.cluster`), resumed from its
checkpoint after a lost worker or an interrupted command (:mod:`dnarod.ensemble.member`), and
reduced on the worker to a row of observables (:mod:`dnarod.ensemble.reduce`, or a protocol's
own, :mod:`dnarod.ensemble.protocol`); the rows form one table (:mod:`dnarod.ensemble.results`).

>>> from dnarod.ensemble import Ensemble                            # doctest: +SKIP
>>> ens = Ensemble.from_toml("examples/force_extension.toml", "fx").run()  # doctest: +SKIP
>>> ens.results().to_pylist()   # doctest: +SKIP
"""
from .cluster import WORKER_ENV, connect, local_cluster, slurm_cluster
from .ensemble import Ensemble
from .member import run_member
from .protocol import DEFAULT as DEFAULT_PROTOCOL, PROTOCOLS, build_runspec, register_protocol
from .reduce import reduce_run
from .schema import Key, SpecError
from .spec import EnsembleSpec, Member, load_spec, member_id, parse_spec

__all__ = ["Ensemble", "EnsembleSpec", "Member", "Key", "SpecError", "load_spec", "parse_spec", "member_id",
           "run_member", "reduce_run", "build_runspec", "register_protocol", "PROTOCOLS", "DEFAULT_PROTOCOL",
           "local_cluster", "connect", "slurm_cluster", "WORKER_ENV"]
