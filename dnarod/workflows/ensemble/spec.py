"""Reading an ensemble spec (TOML) and expanding it into members with stable ids.

Schema (every table optional except ``[base]``; keys and units in :mod:`dnarod.workflows.ensemble.schema`)::

    [ensemble]
    name = "force-extension"
    combine = "cross"            # or "zip"; zip = [["force_pN", "turns"]] zips some axes only
    replicas = 3                 # seeds seed, seed+1, ... crossed with everything else
    protocol = "magnetic-tweezers"  # optional: a registered protocol (dnarod.workflows.ensemble.protocol)

    [base]                       # one run; units in the keys
    source = "ACGT..."           # sequence | node count | PDB/mmCIF/.npz path (relative to this file)
    time_ns = 1.0
    temperature_K = 300.0
    clamp_first = true

    [axes]                       # settings that vary: a list, {linspace = [a, b, n]} or {logspace = [a, b, n]}
    force_pN = [0.5, 1.0, 2.0, 5.0]
    fasta = "sequences.fa"       # a sequence axis from a FASTA file (source + sequence_name)

    [analysis]
    discard_ns = 0.1
    blocks = 10

A member is a flat dict of canonical settings (the base, overridden by its axis values, plus its
``seed``); its id is the first 12 hex digits of the SHA-256 of the settings as sorted JSON, so
the same settings always give the same id and directory.
"""
from __future__ import annotations

import hashlib
import itertools
import json
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.workflows.ensemble.schema import ANALYSIS_KEYS, ENSEMBLE_KEYS, RUN_KEYS, Key, SpecError, check_distinct, coerce, unknown_key

#: Seed of the first replica when the spec gives none (members must be reproducible to resume).
DEFAULT_SEED = 1
#: Most members a spec may expand to: each member is at least one run folder and one dask task, so more is
#: a typo (an n of 10^9 in a linspace, replicas = 10^6) that would otherwise fill the memory before running.
MAX_MEMBERS = 100_000


@dataclass(frozen=True)
class Member:
    """One run of an ensemble.

    Attributes
    ----------
    id : str
        12 hex digits, SHA-256 of ``settings`` as canonical JSON.
    index : int
        Position in the expansion order.
    settings : dict
        Canonical settings (keys with units, see :data:`dnarod.workflows.ensemble.schema.RUN_KEYS`).
    """

    id: str
    index: int
    settings: dict


def member_id(settings):
    """Stable id of a member: 12 hex digits of SHA-256 of its settings as sorted, compact JSON."""
    text = json.dumps(settings, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:12]


@dataclass
class EnsembleSpec:
    """A parsed, validated spec.

    Attributes
    ----------
    name : str
    base : dict
        Settings shared by every member.
    groups : list of dict
        Axis groups after zipping: each maps keys to equal-length value lists; groups are crossed.
    replicas : int
    protocol : str or None
    analysis : dict
        ``discard_ns``, ``blocks`` and protocol-defined analysis keys.
    axes : list of str
        Varying keys in declaration order (``seed`` last when replicas > 1).
    """

    name: str
    base: dict
    groups: list
    replicas: int = 1
    protocol: str | None = None
    analysis: dict = field(default_factory=dict)
    axes: list = field(default_factory=list)
    description: str = ""

    def members(self):
        """Yield the :class:`Member` s in order (cross product of the groups, replicas innermost)."""
        seed0 = self.base.get("seed", DEFAULT_SEED)
        lengths = [len(next(iter(g.values()))) for g in self.groups]
        index = 0
        for combo in itertools.product(*[range(n) for n in lengths]):
            s = dict(self.base)
            for g, i in zip(self.groups, combo):
                for k, vals in g.items():
                    s[k] = vals[i]
            for r in range(self.replicas):
                m = dict(s)
                m["seed"] = int(s.get("seed", seed0)) + r
                yield Member(member_id(m), index, m)
                index += 1

    def __len__(self):
        n = self.replicas
        for g in self.groups:
            n *= len(next(iter(g.values())))
        return n


def read_fasta(path):
    """(name, sequence) records of a FASTA file; sequences upper-cased, whitespace removed."""
    p = Path(path)
    if not p.is_file():
        raise SpecError(f"[axes] fasta: file not found: {p}")
    records, name, chunks = [], None, []
    try:
        text = p.read_text()
    except (UnicodeDecodeError, OSError) as exc:
        raise SpecError(f"[axes] fasta {p}: not a FASTA text file ({type(exc).__name__}: "
                        f"{' '.join(str(exc).split())[:80]})") from None
    for ln, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if not line or line.startswith(";"):
            continue
        if line.startswith(">"):
            if name is not None:
                records.append((name, "".join(chunks)))
            name, chunks = (line[1:].split() or [f"record{len(records) + 1}"])[0], []
        elif name is None:
            raise SpecError(f"[axes] fasta {p}: line {ln}: sequence before the first '>' header")
        else:
            chunks.append("".join(line.split()).upper())
    if name is not None:
        records.append((name, "".join(chunks)))
    if not records:
        raise SpecError(f"[axes] fasta {p}: no records")
    for name, seq in records:
        if not seq:
            raise SpecError(f"[axes] fasta {p}: record {name!r} has no sequence")
    return records


def _axis_values(key, spec, raw):
    where = f"[axes] {key}"
    if isinstance(raw, dict):
        if len(raw) != 1 or next(iter(raw)) not in ("linspace", "logspace"):
            raise SpecError(f"{where}: a range is {{linspace = [start, stop, n]}} or {{logspace = [start, stop, n]}}")
        kind, args = next(iter(raw.items()))
        if spec.kind is not float:
            raise SpecError(f"{where}: {kind} needs a numeric key, {key} is {spec.kind.__name__}")
        n_ok = isinstance(args, list) and len(args) == 3 and isinstance(args[2], int) and not isinstance(args[2], bool)
        if not n_ok:
            raise SpecError(f"{where}: {kind} = [start, stop, n] with an integer n, got {args!r}")
        a, b, n = coerce("axes", key, Key(key, float, None, ""), args[0]), \
            coerce("axes", key, Key(key, float, None, ""), args[1]), args[2]
        if n < 1:
            raise SpecError(f"{where}: axis of length {n}; give at least one value")
        if n > MAX_MEMBERS:
            raise SpecError(f"{where}: {kind} of {n} values is more than the {MAX_MEMBERS} members an ensemble may "
                            f"have; give a smaller n")
        if kind == "logspace":
            if a <= 0 or b <= 0:
                raise SpecError(f"{where}: logspace needs positive start and stop, got {a}, {b}")
            raw = np.geomspace(a, b, n).tolist()
        else:
            raw = np.linspace(a, b, n).tolist()
        # 12 significant digits: the same spec gives the same values (and ids) on every machine
        raw = [float(f"{v:.12g}") for v in raw]
    if not isinstance(raw, list):
        raise SpecError(f"{where}: an axis is a list of values or a range, got {raw!r}")
    if not raw:
        raise SpecError(f"{where}: axis of length zero; give at least one value")
    vals = [coerce("axes", key, spec, v) for v in raw]
    return check_distinct("axes", key, vals)


def _resolve_source(value, base_dir):
    """Paths (anything naming an existing file, or with a structure/model suffix) become absolute."""
    if value.isdigit():
        return value
    p = Path(value)
    looks_like_file = p.suffix.lower() in (".pdb", ".cif", ".mmcif", ".ent", ".npz", ".gz", ".fa", ".fasta", ".txt") \
        or "/" in value
    cand = p if p.is_absolute() else Path(base_dir) / p
    if cand.is_file():
        return str(cand.resolve())
    if looks_like_file:
        raise SpecError(f"source {value!r}: file not found (relative paths are read from {base_dir})")
    seq = "".join(value.split()).upper()
    return seq


def _check_table(name, table, known):
    if not isinstance(table, dict):
        raise SpecError(f"[{name}] must be a table")
    out = {}
    for key, value in table.items():
        if key not in known:
            raise unknown_key(name, key, known)
        out[key] = coerce(name, key, known[key], value)
    return out


def parse_spec(doc, base_dir=".", protocol_keys=None):
    """Validate a spec document (the dict of a TOML file) into an :class:`EnsembleSpec`.

    Parameters
    ----------
    doc : dict
        Tables ``ensemble``, ``base``, ``axes``, ``analysis``.
    base_dir : path
        Directory relative paths (source, fasta) are read from.
    protocol_keys : dict, optional
        Extra run keys (name -> :class:`~dnarod.workflows.ensemble.schema.Key`) and analysis keys accepted
        because the protocol reads them: ``{"run": {...}, "analysis": {...}}``.

    Raises
    ------
    SpecError
        Unknown table or key, missing or wrong unit, wrong type, zero-length axis, unequal zipped
        axes, a missing file.
    """
    protocol_keys = protocol_keys or {}
    run_keys = {**RUN_KEYS, **protocol_keys.get("run", {})}
    analysis_keys = {**ANALYSIS_KEYS, **protocol_keys.get("analysis", {})}
    for t in doc:
        if t not in ("ensemble", "base", "axes", "analysis"):
            raise SpecError(f"unknown table [{t}]; a spec has [ensemble], [base], [axes] and [analysis]")
    if "base" not in doc:
        raise SpecError("[base] is missing: it holds the run every member starts from (at least source = ...)")
    ens = _check_table("ensemble", doc.get("ensemble", {}), ENSEMBLE_KEYS)
    base = _check_table("base", doc["base"], run_keys)
    analysis = _check_table("analysis", doc.get("analysis", {}), analysis_keys)
    if "source" in base:
        base["source"] = _resolve_source(base["source"], base_dir)
    axes_doc = doc.get("axes", {})
    if not isinstance(axes_doc, dict):
        raise SpecError("[axes] must be a table")
    groups, order = [], []
    for key, raw in axes_doc.items():
        if key == "fasta":
            if not isinstance(raw, str):
                raise SpecError("[axes] fasta: expected a file name")
            p = Path(raw) if Path(raw).is_absolute() else Path(base_dir) / raw
            recs = read_fasta(p)
            groups.append({"source": [s for _, s in recs], "sequence_name": [n for n, _ in recs]})
            order += ["source", "sequence_name"]
            continue
        if key not in run_keys:
            raise unknown_key("axes", key, {**run_keys, "fasta": None})
        vals = _axis_values(key, run_keys[key], raw)
        if key == "source":
            vals = [_resolve_source(v, base_dir) for v in vals]
        groups.append({key: vals})
        order.append(key)
    dup = {k for k in order if order.count(k) > 1}
    if dup:
        raise SpecError(f"[axes] {', '.join(sorted(dup))} given twice (fasta sets source and sequence_name)")
    for k in order:
        if k in base:
            raise SpecError(f"[axes] {k} is also in [base]; give it in one place")
    if protocol_keys.get("needs_source", True) and "source" not in base and "source" not in order:
        raise SpecError("[base] source is missing: a sequence, node count or structure/model file")
    replicas = ens.get("replicas", 1)
    if replicas > 1 and "seed" in order:
        raise SpecError("[ensemble] replicas > 1 with a seed axis: give one or the other")
    zip_groups = ens.get("zip", [])
    if ens.get("combine", "cross") == "zip":
        if zip_groups:
            raise SpecError("[ensemble] combine = 'zip' zips every axis; drop zip = [...] or use combine = 'cross'")
        zip_groups = [[k for g in groups for k in g]] if groups else []
    groups = _zip(groups, zip_groups)
    n_members = replicas
    for g in groups:
        n_members *= len(next(iter(g.values())))
    if n_members > MAX_MEMBERS:
        sizes = " x ".join([str(len(next(iter(g.values())))) for g in groups] + ([f"{replicas} replicas"]
                                                                                 if replicas > 1 else []))
        raise SpecError(f"[axes] {sizes} = {n_members} members, more than {MAX_MEMBERS}; give fewer values or "
                        f"replicas (or split the spec)")
    axes = list(order) + (["seed"] if replicas > 1 else [])
    return EnsembleSpec(name=ens.get("name", "ensemble"), base=base, groups=groups, replicas=replicas,
                        protocol=ens.get("protocol"), analysis=analysis, axes=axes,
                        description=ens.get("description", ""))


def _zip(groups, zip_groups):
    """Merge the groups named in each zip group into one (equal lengths required)."""
    for zg in zip_groups:
        if not (isinstance(zg, list) and zg and all(isinstance(k, str) for k in zg)):
            raise SpecError(f"[ensemble] zip: each entry is a list of axis names, got {zg!r}")
        picked = []
        for k in zg:
            hit = [g for g in groups if k in g]
            if not hit:
                raise SpecError(f"[ensemble] zip: {k!r} is not an axis; axes: "
                                f"{', '.join(k2 for g in groups for k2 in g)}")
            if hit[0] not in picked:
                picked.append(hit[0])
        lengths = {k: len(v) for g in picked for k, v in g.items()}
        if len(set(lengths.values())) > 1:
            raise SpecError(f"[ensemble] zipped axes must have equal lengths, got "
                            f"{', '.join(f'{k}: {n}' for k, n in lengths.items())}")
        merged = {k: v for g in picked for k, v in g.items()}
        at = groups.index(picked[0])
        groups = [g for g in groups if g not in picked]
        groups.insert(min(at, len(groups)), merged)
    return groups


def load_spec(path, protocol_keys=None):
    """Read and validate a TOML spec file (see the module docstring)."""
    p = Path(path)
    if not p.is_file():
        raise SpecError(f"{path}: spec file not found")
    try:
        doc = tomllib.loads(p.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise SpecError(f"{path}: not valid TOML: {exc}") from None
    try:
        return parse_spec(doc, base_dir=p.parent.resolve(), protocol_keys=protocol_keys)
    except SpecError as exc:
        raise SpecError(f"{path}: {exc}") from None


def check_members(members, extra_check=None):
    """Cheap checks of every member on the client: force field names and sequence letters.

    Distinct (source, forcefield, circular, ring) combinations are built once with
    :func:`dnarod.structure.inputs.load_model`; a failure names the member's index and settings.
    """
    from dnarod.structure.inputs import load_model

    seen = {}
    for m in members:
        s = m.settings
        if s.get("turns", 0.0) and s.get("rotation_clamp_kJ_mol") is None:
            raise SpecError(f"member {m.index} ({_label(s)}): turns needs rotation_clamp_kJ_mol in [base] or [axes]")
        if "source" not in s:
            continue
        key = (s["source"], s.get("forcefield", "dna-default"), s.get("circular", False), s.get("ring", False),
               s.get("delta_lk", 0))
        if key in seen:
            continue
        try:
            load_model(*key)
        except DnarodError as exc:
            raise SpecError(f"member {m.index} (source {_short(s['source'])}, forcefield {key[1]}): {exc}") from None
        seen[key] = True
        if extra_check is not None:
            extra_check(m)


def _short(text, n=24):
    return text if len(text) <= n else text[:n] + "..."


def _label(s):
    return ", ".join(f"{k}={_short(str(v))}" for k, v in s.items() if k != "source")
