"""The ensemble spec's keys: names with their units, types, defaults and checks.

A spec is a TOML file with four tables (see :func:`dnarod.workflows.ensemble.spec.load_spec`):
``[ensemble]`` (name, how axes combine, replicas, protocol), ``[base]`` (one run's settings),
``[axes]`` (settings that vary: lists or ranges) and ``[analysis]`` (how members are reduced).
Every physical quantity carries its unit in its key, as in the force-field files
(``force_pN``, ``temperature_K``, ``time_ns``); a key without its unit or with another unit is
refused naming the key and the key to write instead.
"""
from __future__ import annotations

import difflib
from dataclasses import dataclass

from dnarod.core.errors import ParameterError


class SpecError(ParameterError):
    """An ensemble spec (TOML file or dict) is invalid; the message names the table and key."""


@dataclass(frozen=True)
class Key:
    """One settings key: ``kind`` is float, int, bool or str; ``check`` a predicate text."""

    name: str
    kind: type
    default: object
    doc: str
    check: str = ""          # "", ">0", ">=0", ">=2", or "|"-separated allowed strings


#: Settings of one run (``[base]`` and ``[axes]``), in RunSpec units. Defaults are the run layer's.
RUN_KEYS = {k.name: k for k in [
    Key("source", str, None, "DNA sequence (strand I, 5'->3'), node count, or a PDB/mmCIF/.npz path "
        "(relative to the spec file)"),
    Key("sequence_name", str, None, "label of the source (set from FASTA record names)"),
    Key("forcefield", str, "dna-default", "bundled force-field name or .toml path"),
    Key("engine", str, "openmm", "simulation engine", "openmm|lax"),
    Key("platform", str, None, "OpenMM platform (CPU, Reference, CUDA, OpenCL)"),
    Key("time_ns", float, 1.0, "simulated time per member, ns", ">0"),
    Key("temperature_K", float, 300.0, "temperature, K", ">=0"),
    Key("friction_per_ps", float, 1.0, "Langevin friction, 1/ps", ">0"),
    Key("dt_ps", float, None, "time step, ps (default 0.4/omega_max)", ">0"),
    Key("salt_M", float, 0.15, "monovalent salt, mol/L (Debye length)", ">0"),
    Key("excluded_volume", bool, True, "WCA excluded volume between non-neighbouring nodes"),
    Key("electrostatics", bool, True, "Debye-Hueckel electrostatics"),
    Key("charge", str, "calibrated", "non-bonded charge model: calibrated (Poisson-Boltzmann far-field charge, "
        "effective diameter 5.0 nm at 0.15 M) or manning (0.48 e/bp)", "calibrated|manning"),
    Key("cutoff_debye", float, 12.0, "Debye-Hueckel cutoff, Debye lengths", ">0"),
    Key("circular", bool, False, "periodic chain (screw-closed helix)"),
    Key("ring", bool, False, "closed planar ring"),
    Key("delta_lk", int, 0, "with ring: linking number relative to the relaxed ring"),
    Key("start", str, "intrinsic", "starting pose", "intrinsic|equilibrium|minimized"),
    Key("seed", int, 1, "random seed of the member (with replicas: the first replica's; replica r gets seed + r)"),
    Key("frame_interval_ps", float, 1.0, "time between trajectory frames, ps", ">0"),
    Key("checkpoint_interval_ps", float, None, "time between checkpoints, ps (default: the run layer's)", ">0"),
    Key("velocities", bool, False, "store velocities in the trajectory"),
    Key("export", bool, False, "also write trajectory.pdb + .dcd"),
    Key("clamp_first", bool, False, "fix node 0 in space (position and orientation)"),
    Key("axis", str, "end-to-end", "axis of the pulling force, torque and rotation clamp: the initial end-to-end "
        "direction or lab z", "end-to-end|z"),
    Key("force_pN", float, 0.0, "pull the last node along the axis, pN (and node 0 the other way unless "
        "clamp_first)"),
    Key("torque_pN_nm", float, 0.0, "torque on the last node about the axis, pN nm"),
    Key("rotation_clamp_kJ_mol", float, None, "clamp the last node's orientation, stiffness kJ/mol", ">0"),
    Key("turns", float, 0.0, "turn the rotation clamp by this many turns at a constant rate over the run"),
]}

#: ``[ensemble]`` keys.
ENSEMBLE_KEYS = {k.name: k for k in [
    Key("name", str, "ensemble", "label of the ensemble"),
    Key("description", str, "", "free text"),
    Key("combine", str, "cross", "cross: every combination of the axes; zip: axes side by side (equal lengths)",
        "cross|zip"),
    Key("zip", list, [], "groups of axes zipped together (each group then crossed with the rest)"),
    Key("replicas", int, 1, "independent seeds per combination (seed, seed+1, ...)", ">0"),
    Key("protocol", str, None, "a registered protocol (null, force-extension, magnetic-tweezers, torque-turns, "
                               "rings) or an entry point of the group dnarod.protocols: the members' build/reduce"),
]}

#: ``[analysis]`` keys (how a member's run is reduced; not part of a member's identity).
ANALYSIS_KEYS = {k.name: k for k in [
    Key("discard_ns", float, 0.0, "leave out the first part of each run (equilibration), ns", ">=0"),
    Key("blocks", int, 10, "blocks for the block standard errors (at least 2)", ">=2"),
]}

#: Physical quantities and the one key (with its unit) that spells each.
QUANTITIES = {"force": "force_pN", "torque": "torque_pN_nm", "temperature": "temperature_K", "time": "time_ns",
              "salt": "salt_M", "friction": "friction_per_ps", "dt": "dt_ps", "frame_interval": "frame_interval_ps",
              "checkpoint_interval": "checkpoint_interval_ps", "rotation_clamp": "rotation_clamp_kJ_mol",
              "discard": "discard_ns", "timestep": "dt_ps", "temp": "temperature_K"}


def unknown_key(table, key, known):
    """A :class:`SpecError` for ``key`` of ``table``: missing unit, wrong unit, or unknown (with a suggestion)."""
    if key in QUANTITIES:
        return SpecError(f"[{table}] {key}: unit missing; write {QUANTITIES[key]}")
    for q, good in sorted(QUANTITIES.items(), key=lambda kv: -len(kv[0])):
        if key.startswith(q + "_") and good in known:
            return SpecError(f"[{table}] {key}: wrong unit; {q} is given in {good[len(q) + 1:]}: write {good}")
    near = difflib.get_close_matches(key, list(known), n=1)
    hint = f"; did you mean {near[0]}?" if near else f"; known keys: {', '.join(sorted(known))}"
    return SpecError(f"[{table}] unknown key {key!r}{hint}")


def coerce(table, key, spec, value):
    """Check ``value`` against ``spec`` (a :class:`Key`) and return it in its canonical type."""
    where = f"[{table}] {key}"
    if spec.kind is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise SpecError(f"{where}: expected a number, got {value!r}")
        value = float(value)
        if value != value or value in (float("inf"), float("-inf")):
            raise SpecError(f"{where}: must be finite, got {value}")
    elif spec.kind is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise SpecError(f"{where}: expected an integer, got {value!r}")
    elif spec.kind is bool:
        if not isinstance(value, bool):
            raise SpecError(f"{where}: expected true or false, got {value!r}")
    elif spec.kind is str:
        if isinstance(value, int) and not isinstance(value, bool) and key == "source":
            value = str(value)     # a node count written as a number
        if not isinstance(value, str):
            raise SpecError(f"{where}: expected a string, got {value!r}")
    elif spec.kind is list and not isinstance(value, list):
        raise SpecError(f"{where}: expected a list, got {value!r}")
    c = spec.check
    if c == ">0" and not value > 0:
        raise SpecError(f"{where}: must be > 0, got {value}")
    if c == ">=0" and not value >= 0:
        raise SpecError(f"{where}: must be >= 0, got {value}")
    if c == ">=2" and not value >= 2:
        raise SpecError(f"{where}: must be >= 2, got {value}")
    if "|" in c and value not in c.split("|"):
        raise SpecError(f"{where}: must be one of {c.replace('|', ', ')}, got {value!r}")
    return value


def check_distinct(table, key, values):
    """Refuse an axis that repeats a value (the same member twice, or one run counted twice in a curve)."""
    seen = set()
    for v in values:
        if repr(v) in seen:
            raise SpecError(f"[{table}] {key}: repeated values {list(values)} ({v} twice); each member must differ")
        seen.add(repr(v))
    return values


def schema_rows():
    """(table, key, type, default, meaning) for every key: the documentation table."""
    rows = []
    for table, keys in (("ensemble", ENSEMBLE_KEYS), ("base / axes", RUN_KEYS), ("analysis", ANALYSIS_KEYS)):
        for k in keys.values():
            rows.append((table, k.name, k.kind.__name__, k.default, k.doc))
    return rows
