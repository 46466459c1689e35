"""CLI commands on structures: ``steps``, ``pairs``, ``build``, ``rebuild``.

CSV contracts (scripts parse them; do not change the columns):

* ``dnarod steps INPUT --csv OUT``: ``step,bp1,bp2,shift_A,slide_A,rise_A,tilt_deg,roll_deg,
  twist_deg,Omega1_per_nm,Omega2_per_nm,Omega3_per_nm,Gamma1,Gamma2,Gamma3,gap``; one row per
  step, ``step`` counting from 1 along strand I (continuing across duplexes; with ``--duplex``
  a step keeps its number, as in every note), ``bp1``/``bp2`` like ``C-G``. Strains from
  :func:`dnarod.core.strains.strains` of the node frames with the force field's ds (3DNA's
  reversed frames for left-handed steps, so they reproduce the step parameters).
  ``gap`` is empty for a regular step and lists the residue ids of the unpaired (extruded,
  bulged) nucleotides a step crosses (the step is then computed between the flanking pairs,
  as 3DNA reports it).
* ``dnarod pairs INPUT --csv OUT``: ``bp,name,shear_A,stretch_A,stagger_A,buckle_deg,
  propeller_deg,opening_deg``; ``bp`` counts from 1 along strand I, ``name`` like ``C-G``.

Without ``--csv`` a readable table goes to stdout. Notes (what was skipped) go to stderr
with ``--csv`` and into the table as ``#`` lines otherwise. Bad input raises a
:class:`~dnarod.core.errors.DnarodError`, which the ``dnarod`` group prints as one line (exit 2).
"""
from __future__ import annotations

import csv
import io
import re
import copy
from pathlib import Path

import click
import numpy as np

from dnarod.core.errors import StructureError
from dnarod.core.io import check_dir_path, write_text_atomic
from dnarod.core.stepparams import to_angstrom_degrees
from dnarod.core.strains import strains
from dnarod.core.forcefield import load_forcefield
from dnarod.core.model import RodModel

STEP_COLUMNS = ("step", "bp1", "bp2", "shift_A", "slide_A", "rise_A", "tilt_deg", "roll_deg", "twist_deg",
                "Omega1_per_nm", "Omega2_per_nm", "Omega3_per_nm", "Gamma1", "Gamma2", "Gamma3", "gap")
PAIR_COLUMNS = ("bp", "name", "shear_A", "stretch_A", "stagger_A", "buckle_deg", "propeller_deg", "opening_deg")


def _read_pairs_file(path):
    pairs = []
    with open(path, errors="replace") as fh:  # a binary file fails the line check below, naming the line
        for k, line in enumerate(fh, 1):
            line = line.split("#")[0].replace(",", " ").strip()
            if not line:
                continue
            parts = line.split()
            if "\ufffd" in line or "\x00" in line:
                raise StructureError(f"{path}, line {k}: binary data; --pairs takes a text file of residue-id pairs "
                                     f"like 'A:1 B:24', one per line")
            if len(parts) != 2:
                raise StructureError(f"{path}, line {k}: expected two residue ids like 'A:1 B:24', got {line!r}")
            pairs.append((parts[0], parts[1]))
    return pairs


def _parse_map(items):
    out = {}
    for it in items:
        if "=" not in it:
            raise StructureError(f"--map {it!r}: use NAME=LETTER, e.g. --map XYZ=C")
        name, letter = it.split("=", 1)
        if not name.strip():
            raise StructureError(f"--map {it!r}: the residue NAME is empty; use NAME=LETTER, e.g. --map XYZ=C")
        if letter.strip().upper() not in ("A", "C", "G", "T", "U"):
            raise StructureError(f"--map {it!r}: the parent base must be A, C, G, T or U")
        key = name.strip().upper()
        if key in out and out[key] != letter.strip().upper():
            raise StructureError(f"--map {it!r}: {key} is already mapped to {out[key]}; "
                                 f"give one --map per residue name")
        out[key] = letter.strip().upper()
    return out


def _check_names(altloc, ignore, maps):
    """Empty names (they matched nothing, silently) and a residue both ignored and mapped are refused."""
    if altloc is not None and not altloc.strip():
        raise StructureError("--altloc '': give the alternate location to keep (e.g. A), or leave the option out")
    for name in ignore:
        if not name.strip():
            raise StructureError("--ignore '': give a residue name (e.g. HOH)")
        if name.strip().upper() in maps:
            raise StructureError(f"--ignore {name}: the residue is also given to --map; drop one of them")


def structure_options(f):
    """Options shared by the structure commands."""
    f = click.option("--ignore", "ignore", multiple=True, metavar="NAME",
                     help="Residue name to ignore even if it looks like a nucleotide (repeatable).")(f)
    f = click.option("--map", "maps", multiple=True, metavar="NAME=BASE",
                     help="Treat residue NAME as a modified BASE (A, C, G, T, U); repeatable.")(f)
    f = click.option("--pairs", "pairs_file", type=click.Path(exists=True, dir_okay=False),
                     help="File of explicit pairs, one 'A:1 B:24' per line, instead of geometric pairing.")(f)
    f = click.option("--altloc", default=None, help="Alternate location to keep (default: most occupied).")(f)
    f = click.option("--model", "model", default=1, show_default=True, type=int, help="Model number (1-based).")(f)
    return f


def _analyze(path, model, altloc, pairs_file, maps, ignore):
    from dnarod.structure.analysis import analyze_structure  # loads scipy.spatial: not at the CLI's start-up

    extra = _parse_map(maps)
    _check_names(altloc, ignore, extra)
    pairs = _read_pairs_file(pairs_file) if pairs_file else None
    return analyze_structure(path, model=model, altloc=altloc, pairs=pairs, extra_residues=extra,
                             ignore_residues=ignore)


def _output_path(path, option, suffixes, kind, overwrite):
    """Refuse an empty output path, a suffix the writer does not produce and (without ``--overwrite``) a file
    that exists: a name the user gave is never silently replaced or filled with another format."""
    if path is None:
        return None
    if not str(path).strip():
        raise StructureError(f"{option} '': give a file name")
    p = Path(path)
    if p.suffix.lower() not in suffixes:
        raise StructureError(f"{option} {path}: {kind} is written as {' or '.join(suffixes)}; give a file name "
                             f"ending in {suffixes[0]}")
    if p.exists() and not overwrite:
        raise StructureError(f"{option} {path}: the file exists; pass --overwrite to replace it or choose another "
                             f"name")
    check_dir_path(p.parent, f"{option} {path}: its folder")  # before any work: a parent that is a regular file
    return path


def _emit(rows, columns, csv_path, title_lines, notes, fmt):
    if csv_path:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(columns)
        for r in rows:
            w.writerow([f"{v:.6f}" if isinstance(v, float) else v for v in r])
        write_text_atomic(csv_path, buf.getvalue())
        for n in notes:
            click.echo(f"note: {n}", err=True)
        click.echo(f"wrote {len(rows)} rows to {csv_path}")
        return
    for t in title_lines + [f"note: {n}" for n in notes]:
        click.echo(f"# {t}")
    click.echo(" ".join(f"{c:>{w}}" for c, w in zip(columns, fmt)))
    for r in rows:  # Angstrom and degrees to 2 decimals (as 3DNA), strains to 4
        cells = [(f"{v:>{w}.4f}" if c.startswith(("Omega", "Gamma")) else f"{v:>{w}.2f}") if isinstance(v, float)
                 else f"{v!s:>{w}}" for v, w, c in zip(r, fmt, columns)]
        click.echo(" ".join(cells))


def duplex_option(f):
    """``--duplex N`` (1-based), shared by every structure command."""
    return click.option("--duplex", type=int, default=None, metavar="N",
                        help="Duplex number (1-based, as listed by 'dnarod pairs'); default all for steps/pairs, "
                             "the longest for build.")(f)


def _only_duplex(ana, duplex):
    """Restrict an analysis to duplex ``duplex`` (1-based) for the tables."""
    if duplex is None:
        return ana
    from dnarod.structure.selection import choose_duplex  # loads scipy.spatial: not at the CLI's start-up

    if duplex < 1:
        raise StructureError(f"--duplex {duplex}: duplexes are numbered from 1")
    sel = choose_duplex(ana, duplex - 1)

    out = copy.copy(ana)
    out.duplexes = [sel.duplex]
    out.selected = sel
    return out


def _titles(ana):
    sel = getattr(ana, "selected", None)
    if sel is not None:
        return [sel.report()]
    out = [f"{ana.source}: model {ana.structure.model} of {ana.structure.n_models}, "
           f"{len(ana.structure.nucleotides)} nucleotides, {len(ana.duplexes)} duplex(es)"]
    for k, d in enumerate(ana.duplexes):
        out.append(f"duplex {k + 1}: {d.n_bp} bp, strand I {d.strand1[0].rid}..{d.strand1[-1].rid}, "
                   f"strand II {d.strand2[0].rid}..{d.strand2[-1].rid}" + (" (circular)" if d.circular else ""))
    return out


def step_rows(ana, ds, notes=None):
    """Rows of the ``steps`` table (lengths in Angstrom, angles in degrees, strains per nm).

    A step that is not stacked (node frames turning by nearly a half turn) keeps its 3DNA
    parameters and gets NaN strains; a line naming it is appended to ``notes``.
    """
    # loads scipy.spatial: not at the CLI's start-up
    from dnarod.structure.analysis import describe_unstacked, unstacked_steps

    rows = []
    for d in ana.duplexes:
        if d.n_bp < 2:
            continue
        bad = unstacked_steps(d)
        sp = to_angstrom_degrees(d.step_params)
        O, F = d.bp_origins, d.bp_frames
        Om = np.full((d.n_bp - 1, 3), np.nan)
        Ga = np.full((d.n_bp - 1, 3), np.nan)
        good = np.setdiff1d(np.arange(d.n_bp - 1), bad)
        if good.size:  # each step on its own (the strain map is undefined at the bad ones)
            o, g = strains(np.stack([O[good], O[good + 1]], axis=1), np.stack([F[good], F[good + 1]], axis=1), ds)
            Om[good], Ga[good] = o[:, 0], g[:, 0]
        for k in bad:
            if notes is not None:
                notes.append(f"{describe_unstacked(d, k)}: not a stacked step; its strains are left NaN")
        labels = d.bp_labels
        gaps = d.gaps or [""] * (d.n_bp - 1)
        for i in range(d.n_bp - 1):
            k = d.first_step + i  # the same number in every table and message, also with --duplex
            rows.append((k, labels[i], labels[i + 1], *map(float, sp[i]), *map(float, Om[i]), *map(float, Ga[i]),
                         gaps[i].replace(" ", ";")))
    return rows


def pair_rows(ana):
    """Rows of the ``pairs`` table (lengths in Angstrom, angles in degrees)."""
    rows, k = [], 0
    for d in ana.duplexes:
        bp = to_angstrom_degrees(d.bp_params)
        for i, lab in enumerate(d.bp_labels):
            k += 1
            rows.append((k, lab, *map(float, bp[i])))
    return rows


@click.command("steps")
@click.argument("input_path", metavar="INPUT", type=click.Path(dir_okay=False))
@click.option("--csv", "csv_path", type=click.Path(dir_okay=False), help="Write CSV here instead of a table.")
@click.option("-f", "--forcefield", default="dna-default", show_default=True,
              help="Force field whose ds scales the strains.")
@duplex_option
@structure_options
def steps(input_path, csv_path, forcefield, duplex, model, altloc, pairs_file, maps, ignore):
    """Step parameters (3DNA convention) and SMK strains of every base-pair step of INPUT (PDB/mmCIF)."""
    _output_path(csv_path, "--csv", (".csv",), "a table", True)
    ff = load_forcefield(forcefield)
    ana = _only_duplex(_analyze(input_path, model, altloc, pairs_file, maps, ignore), duplex)
    extra = []
    rows = step_rows(ana, ff.ds, extra)
    title = _titles(ana) + [f"strains with ds = {ff.ds:g} nm ({ff.name}); Omega in 1/nm, Gamma dimensionless"]
    _emit(rows, STEP_COLUMNS, csv_path, title, ana.skipped + extra, (4, 5, 5) + (8,) * 6 + (13,) * 3 + (7,) * 3 + (4,))


@click.command("pairs")
@click.argument("input_path", metavar="INPUT", type=click.Path(dir_okay=False))
@click.option("--csv", "csv_path", type=click.Path(dir_okay=False), help="Write CSV here instead of a table.")
@duplex_option
@structure_options
def pairs(input_path, csv_path, duplex, model, altloc, pairs_file, maps, ignore):
    """Base pairs of INPUT (PDB/mmCIF) and their six parameters (3DNA convention)."""
    _output_path(csv_path, "--csv", (".csv",), "a table", True)
    ana = _only_duplex(_analyze(input_path, model, altloc, pairs_file, maps, ignore), duplex)
    rows = pair_rows(ana)
    if not csv_path:  # the readable table also names the residues and the pair class
        ids = [f"{a.rid}/{b.rid}" for d in ana.duplexes for a, b in zip(d.strand1, d.strand2)]
        kinds = [n for d in ana.duplexes for n in d.names]
        rows = [r + (i, c) for r, i, c in zip(rows, ids, kinds)]
        _emit(rows, PAIR_COLUMNS + ("residues", "class"), None, _titles(ana), ana.skipped,
              (4, 5) + (13,) * 6 + (14, 7))
        return
    _emit(rows, PAIR_COLUMNS, csv_path, _titles(ana), ana.skipped, ())


@click.command("build")
@click.argument("input_path", metavar="INPUT", required=False, type=click.Path(dir_okay=False))
@click.option("--sequence", help="Build the intrinsic shape of this sequence instead of reading INPUT.")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="Model file (.npz).")
@click.option("-f", "--forcefield", default="dna-default", show_default=True, help="Force field (name or .toml).")
@click.option("--intrinsic", type=click.Choice(["sequence", "structure"]), default="sequence", show_default=True,
              help="Intrinsic shape: the force field's for the sequence, or the structure's own step parameters "
                   "(stiffness still from --forcefield).")
@click.option("--overwrite", is_flag=True, help="Replace an existing model file.")
@duplex_option
@structure_options
def build(input_path, sequence, output, forcefield, intrinsic, duplex, model, altloc, pairs_file, maps, ignore,
          overwrite):
    """A dnarod model (.npz) from a structure INPUT (nodes at its base-pair frames) or from --sequence."""
    # loads scipy.spatial: not at the CLI's start-up
    from dnarod.structure.builders import model_from_sequence, model_from_structure

    if sequence is not None and not re.fullmatch(r"[ACGTacgt]+", sequence):
        bad = re.search(r"[^ACGTacgt]", sequence)
        raise StructureError(f"--sequence {sequence!r}: " + (f"{bad.group()!r} is not a DNA base (A, C, G, T)" if bad
                                                              else "empty; give the strand-I letters A, C, G, T"))
    if (input_path is None) == (sequence is None):
        raise StructureError("build: give either INPUT (a PDB/mmCIF file) or --sequence, not both or neither")
    if sequence is not None and (intrinsic == "structure" or duplex is not None):
        raise StructureError("build: --intrinsic structure and --duplex need a structure INPUT, not --sequence")
    if duplex is not None and duplex < 1:
        raise StructureError(f"--duplex {duplex}: duplexes are numbered from 1")
    _output_path(output, "-o", (".npz",), "a dnarod model", overwrite)
    if sequence is not None:
        m = model_from_sequence(sequence, forcefield)
    else:
        ana = _analyze(input_path, model, altloc, pairs_file, maps, ignore)
        m = model_from_structure(analysis=ana, forcefield=forcefield, duplex=None if duplex is None else duplex - 1,
                                 intrinsic=intrinsic)
    m.save(output)
    if m.metadata.get("selection"):
        click.echo(f"input: {m.metadata['selection']}")
    click.echo(f"wrote {output}: {m.n_nodes} nodes, ds = {m.ds:g} nm, force field {forcefield}")


@click.command("rebuild")
@click.argument("model_path", metavar="MODEL", type=click.Path(exists=True, dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="All-atom file to write: .pdb or .cif (PDBx/mmCIF).")
@click.option("--hydrogens/--no-hydrogens", default=True, show_default=True, help="Write hydrogens.")
@click.option("--minimize/--no-minimize", default=True, show_default=True,
              help="Close the backbone with Amber14 (default); --no-minimize writes the rigid placement only "
                   "(standard bases in the frames, fibre backbone; O3'-P links not closed).")
@click.option("--overwrite", is_flag=True, help="Replace an existing output file.")
def rebuild(model_path, output, hydrogens, minimize, overwrite):
    """An all-atom PDB/mmCIF from a dnarod model file (.npz): standard bases in the node frames and a
    backbone closed by restrained Amber14 minimisation (OBC2), checked bond by bond."""
    # loads scipy.spatial: not at the CLI's start-up
    from dnarod.structure.rebuild import base_pair_frames, rebuild_model

    _output_path(output, "-o", (".pdb", ".cif", ".mmcif"), "an all-atom structure", overwrite)
    m = RodModel.load(model_path)
    if not minimize:
        if output.lower().endswith((".cif", ".mmcif")):
            raise StructureError("rebuild --no-minimize writes PDB only; give -o FILE.pdb")
        xyz, atoms = rebuild_model(m, output)
        click.echo(f"wrote {output}: {len(atoms)} atoms, {2 * m.n_nodes} nucleotides (rigid placement, backbone "
                   f"not closed)")
        return
    from dnarod.structure.allatom import rebuild_allatom  # loads scipy.spatial: not at the CLI's start-up

    if not m.sequence:
        raise StructureError("rebuild: the model has no sequence; build it from a sequence or a structure")
    bp = np.asarray(m.metadata["bp_params"], float) if "bp_params" in m.metadata else None
    res = rebuild_allatom(base_pair_frames(m), m.positions, m.sequence, bp, m.metadata.get("sequence2"))
    res.write(output, hydrogens=hydrogens)
    n_atoms = sum(1 for a in res.topology.atoms() if hydrogens or a.element.symbol != "H")
    click.echo(f"wrote {output}: {n_atoms} atoms, {2 * m.n_nodes} nucleotides")
    for line in res.report.summary():
        click.echo(f"  {line}", err=True)
