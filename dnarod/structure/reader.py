"""Read nucleotides from PDB or mmCIF files (through gemmi) into plain records.

What the reader does (and reports):

* parses PDB and mmCIF with gemmi (a maintained structure library; no column parser here);
* picks one model (``model``, 1-based, default the first);
* keeps nucleotides only: residue names are normalised through 3DNA's ``3dna_baselist.dat``
  (``DA``/``A``/``ADE``, modified residues such as ``5CM`` -> parent ``C``), terminal variants
  (``DA5``, ``DT3``, ``RA5``, ...) and gemmi's table of the PDB chemical components;
* ignores hydrogens, water, amino acids, ions and other ligands (counted in ``skipped``);
* a nucleotide-like residue that is not part of a DNA/RNA chain (a ligand such as cAMP, ``CMP``,
  or a free ``ATP``) is a ligand, not an unpaired nucleotide: a residue is part of a chain when
  it is linked O3'-P to another residue (``LINK_CUTOFF``) or gemmi puts it in a polymer
  entity (mmCIF ``_entity``, or the PDB chain before its ``TER``); an unlinked residue of a
  non-polymer entity, or an unlinked modified residue where the entity is unknown, is a ligand;
* modified nucleotides inside a chain (``5CM``, ``8OG``, ...) are kept as their parent base and
  listed in ``NucleicStructure.notes``;
* old atom names are translated (``O5*`` -> ``O5'``, ``O1P`` -> ``OP1``, ``C5M`` -> ``C7``);
* alternate locations: the altloc with the highest occupancy in each residue (or the one
  asked for with ``altloc``); conflicting altlocs and duplicate atoms are errors.

Coordinates are returned in nm (converted from the files' Angstrom at this edge).
Every problem raises :class:`~dnarod.core.errors.StructureError` naming the file, chain and residue.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from dnarod.core.errors import StructureError

#: Watson-Crick complement of a base letter (U pairs with A, inosine I with C): the one table of it.
COMPLEMENT = {"A": "T", "T": "A", "G": "C", "C": "G", "U": "A", "I": "C"}
from dnarod.structure._data import data_file

WATER = {"HOH", "WAT", "H2O", "DOD", "TIP", "TIP3", "TIP4", "SOL", "SPC", "T3P", "T4P"}
BACKBONE = {"P", "OP1", "OP2", "OP3", "O5'", "C5'", "C4'", "O4'", "C3'", "O3'", "C2'", "O2'", "C1'",
            "HO5'", "HO3'"}
PYRIMIDINE_RING = ("N1", "C2", "N3", "C4", "C5", "C6")
OLD_NAMES = {"O1P": "OP1", "O2P": "OP2", "O3P": "OP3", "C5M": "C7"}
LINK_CUTOFF = 2.5  # Angstrom: O3'(i)-P(j) distance taken as a covalent polymer link (bond 1.6 A)
TERMINAL_NAME = re.compile(r"^(?:D|R)?([ACGTUI])(?:5|3|N)?$")


@dataclass
class Nucleotide:
    """One nucleotide of the chosen model.

    Attributes
    ----------
    chain : str
    number : int
        Residue sequence number.
    icode : str
        Insertion code ('' if none).
    resname : str
        Residue name as in the file.
    base : str
        Parent base letter (A, C, G, T, U, I).
    modified : bool
        True if the residue is a modified base mapped to its parent.
    index : int
        Position among the nucleotides of the model, file order.
    atoms : dict
        Atom name (normalised) -> coordinates, ndarray shape (3,), nm.
    atom_index : dict
        Atom name -> 0-based index of the atom among all atoms of the model in gemmi's order
        (hydrogens, water and protein included), for matching trajectory coordinates.
    altlocs : tuple of str
        Alternate location codes present in the residue (empty if none).
    altloc : str
        The one kept ('' if none).
    """

    chain: str
    number: int
    icode: str
    resname: str
    base: str
    modified: bool
    index: int
    atoms: dict = field(repr=False)
    atom_index: dict = field(repr=False, default_factory=dict)
    altlocs: tuple = ()
    altloc: str = ""

    @property
    def rid(self):
        """Residue id ``chain:number[icode]``, e.g. ``A:5``."""
        return f"{self.chain}:{self.number}{self.icode}"

    @property
    def label(self):
        """``chain A residue 5 (DA)``, for messages."""
        return f"chain {self.chain} residue {self.number}{self.icode} ({self.resname})"

    @property
    def letter(self):
        """Parent letter, lower case for a modified base (3DNA's convention)."""
        return self.base.lower() if self.modified else self.base


@dataclass
class NucleicStructure:
    """The nucleotides of one model of a structure file.

    Attributes
    ----------
    source : str
        File name (or ``"<text>"``) used in messages.
    model : int
        The model read (1-based).
    n_models : int
    n_atoms : int
        Atoms in the model (all kinds), the length of a matching trajectory frame.
    nucleotides : list of Nucleotide
    skipped : list of str
        What was ignored and why (one line per kind or residue).
    notes : list of str
        What was kept but changed, e.g. modified nucleotides modelled as their parent base.
    """

    source: str
    model: int
    n_models: int
    n_atoms: int
    nucleotides: list
    skipped: list
    notes: list = field(default_factory=list)


@lru_cache(maxsize=1)
def base_name_map():
    """Residue name -> letter from 3DNA's ``3dna_baselist.dat`` (lower case = modified base)."""
    out = {}
    for line in data_file("standard_bases", "3dna_baselist.dat").read_text().splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        name, letter = line[:3].strip().upper(), line[3:].split()[0]
        out[name] = letter
    return out


def normalise_residue_name(name, extra=None):
    """Parent letter and modified flag for a residue name, or ``None`` if it is not a nucleotide.

    Parameters
    ----------
    name : str
        Residue name as in the file (e.g. ``"DA"``, ``"ADE"``, ``"DA5"``, ``"5CM"``).
    extra : dict, optional
        User map of residue names to parent letters (``{"XYZ": "C"}``), taking precedence.

    Returns
    -------
    (str, bool) or None
        Upper-case parent letter and whether the residue is modified.
    """
    key = name.strip().upper()
    if extra and key in extra:
        letter = extra[key].upper()
        return letter, letter != key.lstrip("D")
    table = base_name_map()
    if key in table:
        letter = table[key]
        return letter.upper(), letter.islower()
    m = TERMINAL_NAME.match(key)
    if m:
        return m.group(1), False
    return _gemmi_parent(key)


@lru_cache(maxsize=None)
def _gemmi_parent(key):
    import gemmi

    info = gemmi.find_tabulated_residue(key)
    if info is not None and info.is_nucleic_acid():
        code = info.one_letter_code
        if code and code.upper() in "ACGTUI":
            return code.upper(), True
    return None


def _normalise_atom_name(name):
    name = name.strip().replace("*", "'").upper()
    return OLD_NAMES.get(name, name)


def _is_hydrogen(atom, name):
    el = atom.element.name.upper()
    if el in ("H", "D"):
        return True
    return el in ("", "X") and name[:1] in ("H", "D") or name[:1].isdigit() and name[1:2] == "H"


def _looks_nucleotide(residue):
    names = {_normalise_atom_name(a.name) for a in residue}
    return len(names.intersection(PYRIMIDINE_RING)) >= 3 and "C1'" in names


def _linked_residues(model):
    """Residues of ``model`` bonded O3'-P to another residue: set of (chain index, residue index).

    A polymer link is the covalent O3'(i)-P(j) bond between two residues (within
    ``LINK_CUTOFF``); a cyclic phosphate inside one residue (cAMP) does not count.
    """
    from scipy.spatial import cKDTree

    o3, p = [], []
    for ci, chain in enumerate(model):
        for ri, res in enumerate(chain):
            for atom in res:
                name = _normalise_atom_name(atom.name)
                if name in ("O3'", "P"):
                    (o3 if name == "O3'" else p).append(((ci, ri), (atom.pos.x, atom.pos.y, atom.pos.z)))
    if not o3 or not p:
        return set()
    tree = cKDTree(np.array([x for _, x in p]))
    linked = set()
    for key, x in o3:
        for j in tree.query_ball_point(x, LINK_CUTOFF):
            if p[j][0] != key:
                linked.update((key, p[j][0]))
    return linked


def _is_ligand(res, key, linked, modified):
    """True if a nucleotide-like residue is a free ligand rather than part of a DNA/RNA chain."""
    import gemmi

    if key in linked:
        return False
    et = res.entity_type
    if et == gemmi.EntityType.Polymer:
        return False  # in a chain (e.g. at a chain break)
    if et in (gemmi.EntityType.NonPolymer, gemmi.EntityType.Branched, gemmi.EntityType.Water):
        return True
    return bool(modified)  # entity unknown: an unlinked non-standard nucleotide is a ligand


def _read_gemmi(path, text, source):
    import gemmi

    try:
        if text is not None:
            if "\0" in text:
                raise StructureError(f"{source}: binary data, not a PDB or mmCIF text")
            stripped = text.lstrip()
            if stripped.startswith("data_"):
                doc = gemmi.cif.read_string(text)
                return gemmi.make_structure_from_block(doc.sole_block())
            return gemmi.read_pdb_string(text)
        p = Path(path)
        if not p.is_file():
            raise StructureError(f"{source}: no such file")
        head = p.read_bytes()[:4096]
        if head[:2] == b"\x1f\x8b":  # gzip (gemmi reads it directly): check the decompressed start
            import gzip

            try:
                with gzip.open(p) as fh:
                    head = fh.read(4096)
            except (OSError, EOFError) as exc:
                raise StructureError(f"{source}: broken gzip file ({exc})") from None
        if not head.strip():
            raise StructureError(f"{source}: the file is empty; give a PDB or mmCIF file")
        if b"\0" in head or _mostly_binary(head):
            raise StructureError(f"{source}: binary data, not a PDB or mmCIF text file")
        # The format is taken from the content, not the name: a PDB file named .cif (or an mmCIF file named
        # .pdb, .ent, .txt) is read as what it is. Keep chain parts apart so that atoms stay in file order
        # (trajectory atom indices).
        fmt = gemmi.CoorFormat.Mmcif if _looks_like_cif(head) else gemmi.CoorFormat.Pdb
        return gemmi.read_structure(str(p), merge_chain_parts=False, format=fmt)
    except StructureError:
        raise
    except Exception as exc:  # gemmi raises RuntimeError/ValueError/... with the line; keep its words
        msg = str(exc).replace("\n", " ").strip()
    # Old PDB files carry the ID code and a serial in columns 73-80, where gemmi expects the
    # element and charge: retry reading only the first 72 columns.
    try:
        if text is not None and not text.lstrip().startswith("data_"):
            return gemmi.read_pdb_string(text, max_line_length=72)
        if path is not None and not _looks_like_cif(head):
            return gemmi.read_pdb(str(path), max_line_length=72)
    except Exception:  # same as above: report the first error
        pass
    raise StructureError(f"{source}: cannot parse as PDB/mmCIF (truncated or malformed?): {msg}")


def _looks_like_cif(head):
    """True if the first bytes of a file are mmCIF (its first line that is not blank or a comment is a
    ``data_`` block header), False for anything else (read as PDB)."""
    for line in head.splitlines():
        line = line.strip()
        if line and not line.startswith(b"#"):
            return line.startswith(b"data_")
    return False


def _mostly_binary(head):
    text_bytes = bytes(range(32, 127)) + b"\n\r\t\f"
    bad = sum(1 for b in head if b not in text_bytes)
    return bad > 0.05 * len(head)


def _choose_altloc(res_atoms, altloc, source, label):
    """Keep one conformer per residue. ``res_atoms``: list of (name, altloc, occ, xyz, index)."""
    by_name = {}
    for name, alt, occ, xyz, idx in res_atoms:
        by_name.setdefault(name, []).append((alt, occ, xyz, idx))
    alts = sorted({alt for entries in by_name.values() for alt, *_ in entries if alt})
    for name, entries in by_name.items():
        codes = [alt for alt, *_ in entries]
        if len(codes) != len(set(codes)):
            dup = [c for c in codes if codes.count(c) > 1][0]
            where = f" with altloc {dup!r}" if dup else ""
            raise StructureError(f"{source}: {label}: duplicate atom {name}{where} ({codes.count(dup)} copies); "
                                 f"remove the extra copies or give them distinct altloc codes")
        if len(entries) > 1:
            if "" in codes:
                raise StructureError(f"{source}: {label}: conflicting altlocs for atom {name}: it is given both "
                                     f"without an altloc and with altloc(s) {[c for c in codes if c]}")
            total = sum(occ for _, occ, *_ in entries)
            if altloc is None and total > 1.0 + 0.02:
                raise StructureError(f"{source}: {label}: conflicting altlocs for atom {name}: occupancies "
                                     f"{[round(o, 2) for _, o, *_ in entries]} of altlocs {codes} sum to "
                                     f"{total:.2f} > 1; fix the occupancies or choose one (altloc=, CLI --altloc)")
    if altloc is None and alts:
        occ_sum = {a: sum(o for e in by_name.values() for alt, o, *_ in e if alt == a) for a in alts}
        altloc = max(alts, key=lambda a: (occ_sum[a], -ord(a[0])))
    atoms, index = {}, {}
    for name, entries in by_name.items():
        match = [e for e in entries if e[0] in ("", altloc)]
        pick = match[0] if match else entries[0]  # an atom present only in another conformer
        atoms[name] = pick[2]
        index[name] = pick[3]
    return atoms, index, (altloc if alts else "")


def read_structure(path=None, text=None, model=1, altloc=None, extra_residues=None, ignore_residues=()):
    """Read the nucleotides of one model of a PDB or mmCIF file.

    Parameters
    ----------
    path : str or Path, optional
        Structure file (PDB, mmCIF; gzip accepted by gemmi).
    text : str, optional
        The file contents instead of a path (PDB, or mmCIF starting with ``data_``).
    model : int
        Model number, 1-based (the n-th model in the file).
    altloc : str, optional
        Alternate location to keep; default: the most occupied one in each residue.
    extra_residues : dict, optional
        Extra residue names -> parent base letter, e.g. ``{"XYZ": "C"}``.
    ignore_residues : iterable of str
        Residue names to skip even if they look like nucleotides.

    Returns
    -------
    NucleicStructure
        Coordinates in nm.

    Raises
    ------
    StructureError
        Empty, binary or malformed input, a missing model, no nucleic acid, duplicate atoms,
        conflicting altlocs, a nucleotide-like residue of unknown name, non-finite coordinates.
    """
    source = str(path) if path is not None else "<text>"
    if path is None and text is None:
        raise StructureError("read_structure: give a path or text")
    st = _read_gemmi(path, text, source)
    n_models = len(st)
    if n_models == 0 or all(len(m) == 0 for m in st):
        raise StructureError(f"{source}: no atoms found (empty, truncated or not a PDB/mmCIF file)")
    if not isinstance(model, (int, np.integer)) or not 1 <= model <= n_models:
        raise StructureError(f"{source}: model {model!r} does not exist; the file has {n_models} model(s) (1-based)")
    extra = {k.strip().upper(): v for k, v in (extra_residues or {}).items()}
    ignore = {n.strip().upper() for n in ignore_residues}
    altloc = (altloc or None)
    counts = {"water": 0, "amino acid": 0, "hydrogen atoms": 0, "other (ions, ligands)": 0}
    others = set()
    nucleotides, skipped, seen, ligands, modified_nts = [], [], {}, [], []
    alt_codes = set()  # altloc codes present in the nucleotides (an asked-for code must be one of them)
    atom_counter = 0
    try:
        linked = _linked_residues(st[model - 1])
        for ci, chain in enumerate(st[model - 1]):
            for ri, res in enumerate(chain):
                first_index = atom_counter
                atom_counter += len(res)
                name = res.name.strip().upper()
                label = f"chain {chain.name} residue {res.seqid.num}{res.seqid.icode.strip()} ({res.name})"
                if name in ignore:
                    skipped.append(f"{label}: ignored on request")
                    continue
                if name in WATER:
                    counts["water"] += 1
                    continue
                parent = normalise_residue_name(name, extra)
                if parent is None:
                    info = _tabulated(name)
                    if info is not None and info.is_water():
                        counts["water"] += 1
                    elif info is not None and info.is_amino_acid():
                        counts["amino acid"] += 1
                    elif _looks_nucleotide(res):
                        raise StructureError(
                            f"{source}: {label}: unknown residue name {res.name!r} with nucleotide atoms; map it "
                            f"to its parent base (extra_residues={{'{name}': 'C'}}, CLI --map {name}=C) or ignore "
                            f"it (ignore_residues, CLI --ignore {name})")
                    else:
                        counts["other (ions, ligands)"] += 1
                        others.add(name)
                    continue
                base, modified = parent
                if _is_ligand(res, (ci, ri), linked, modified):
                    ligands.append(f"{res.name.strip()} {chain.name}:{res.seqid.num}{res.seqid.icode.strip()}")
                    continue
                if base == "P":
                    skipped.append(f"{label}: pseudouridine is not supported (no standard base); skipped")
                    continue
                raw = []
                for k, atom in enumerate(res):
                    aname = _normalise_atom_name(atom.name)
                    if _is_hydrogen(atom, aname):
                        counts["hydrogen atoms"] += 1
                        continue
                    pos = atom.pos
                    raw.append((aname, atom.altloc.strip("\0 "), float(atom.occ),
                                (pos.x, pos.y, pos.z), first_index + k))
                alt_codes.update(r[1] for r in raw if r[1])
                atoms, index, kept = _choose_altloc(raw, altloc, source, label)
                if not atoms:
                    skipped.append(f"{label}: no heavy atoms; skipped")
                    continue
                xyz = np.array(list(atoms.values()), dtype=float)
                if not np.isfinite(xyz).all() or np.abs(xyz).max() > 1e6:
                    raise StructureError(f"{source}: {label}: non-finite or absurd coordinates")
                key = (chain.name, res.seqid.num, res.seqid.icode.strip())
                xyz_nm = {k: 0.1 * np.array(v) for k, v in atoms.items()}
                if key in seen:  # the residue's atoms come in several blocks: merge them unless they repeat
                    prev = seen[key]
                    both = sorted(set(prev.atoms) & set(xyz_nm))
                    if both or prev.resname != res.name.strip():
                        what = f"duplicate atom {both[0]}" if both else f"also named {prev.resname}"
                        raise StructureError(f"{source}: {label}: residue appears twice in chain {chain.name} "
                                             f"({what}); remove the duplicate copy")
                    prev.atoms.update(xyz_nm)
                    prev.atom_index.update(index)
                    continue
                nt = Nucleotide(chain.name, res.seqid.num, res.seqid.icode.strip(), res.name.strip(), base, modified,
                                len(nucleotides), xyz_nm, index, tuple(sorted({r[1] for r in raw if r[1]})), kept)
                seen[key] = nt
                nucleotides.append(nt)
                if modified:
                    modified_nts.append(f"{nt.rid} {nt.resname}->{base}")
        if altloc is not None and altloc not in alt_codes:
            present = ", ".join(sorted(alt_codes)) if alt_codes else "none"
            raise StructureError(f"{source}: altloc {altloc!r} does not occur in the nucleotides (altlocs present: "
                                 f"{present}); give one of those or leave altloc unset")
    except UnicodeDecodeError:
        raise StructureError(f"{source}: non-ASCII bytes in a chain, residue or atom name near atom "
                             f"{atom_counter}; PDB/mmCIF names must be plain text") from None
    for what, n in counts.items():
        if n:
            extra_txt = f" ({', '.join(sorted(others))})" if what.startswith("other") else ""
            skipped.append(f"ignored {n} {what}{extra_txt}")
    if ligands:
        skipped.append(f"ignored {len(ligands)} nucleotide-like ligand{'s' if len(ligands) > 1 else ''} not linked "
                       f"into a DNA/RNA chain ({', '.join(ligands)})")
    notes = []
    if modified_nts:
        notes.append(f"modified nucleotides modelled as their parent base: {', '.join(modified_nts)}")
    if not nucleotides:
        found = [f"{n} {w}" for w, n in counts.items() if n]
        if ligands:
            found.append(f"{len(ligands)} nucleotide-like ligands not in a chain")
        raise StructureError(f"{source}: no nucleic acid found in model {model} "
                             f"({atom_counter} atoms; {', '.join(found) or 'none recognised'})")
    return NucleicStructure(source, int(model), n_models, atom_counter, nucleotides, skipped, notes)


@lru_cache(maxsize=None)
def _tabulated(name):
    import gemmi

    return gemmi.find_tabulated_residue(name)
