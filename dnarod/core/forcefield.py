"""Parameter sets (force fields): loading, unit and schema checks, sequence mapping.

A force field is a TOML file in ``forcefields/`` (or any path). Every quantity is a table
``{ value = ..., unit = "..." }``; a missing or unknown unit is an error. Three kinds:

``uniform``
    One step type: ``[step]`` holds ``ds``, ``Omega0``, ``Gamma0``, ``A``, ``B``, ``C``.
``sequence-3dna``
    Sequence dependent, given as 3DNA Gaussian step models (mean step parameters in
    Angstrom/degrees and 6x6 force constants in kT) in CSV tables; converted to Cayley
    coordinates through the Jacobian of the strain map at each mean step
    (:mod:`dnarod.core.conversion`).
``sequence-cayley``
    Sequence dependent, given directly in Cayley coordinates: one ``[steps.XY]`` table per
    dinucleotide with ``Omega0``, ``Gamma0``, ``A``, ``B``, ``C`` (what ``dnarod analyze`` writes).
``material``
    A uniform circular rod from material constants (Young's and shear moduli, radius,
    density, shear coefficient): any shearable, extensible rod, not only DNA.

Loading a set for a sequence (strand I, 5'->3') gives the per-step
:class:`~dnarod.core.parameters.StepParameters`.
"""
from __future__ import annotations

import csv
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dnarod.core.conversion import stiffness_from_step_coordinates
from dnarod.core.errors import ParameterError
from dnarod.core.model import RodModel
from dnarod.core.parameters import StepParameters, check_stiffness
from dnarod.core.strains import Closure, chain_from_strains
from dnarod.core.units import kT
from dnarod.core.units import KG_PER_M3, PA, PN
from dnarod.core.io import write_text_atomic


#: unit string -> (dimension, factor to dnarod's internal unit)
UNITS = {
    "nm": ("length", 1.0), "A": ("length", 0.1), "m": ("length", 1e9),
    "1/nm": ("inverse length", 1.0), "1": ("dimensionless", 1.0),
    "kJ/mol*nm": ("energy*length", 1.0), "kJ/mol": ("energy", 1.0), "kJ/mol/nm": ("energy/length", 1.0),
    "pN*nm^2": ("energy*length", PN), "pN*nm": ("energy", PN), "pN": ("energy/length", PN),
    "amu": ("mass", 1.0), "amu*nm^2": ("moment of inertia", 1.0),
    "Pa": ("pressure", PA), "GPa": ("pressure", 1e9 * PA),
    "kg/m^3": ("density", KG_PER_M3),  # amu/nm^3
    "K": ("temperature", 1.0),
}

#: The installed package (``dnarod/``) and the source tree above it.
_PACKAGE = Path(__file__).resolve().parents[1]
SEARCH_DIRS = [
    _PACKAGE / "_bundled" / "forcefields",  # installed wheel
    _PACKAGE.parent / "forcefields",  # source tree / editable install
]


def data_dir() -> Path:
    """The bundled ``data/`` directory (installed wheel or source tree)."""
    for d in (_PACKAGE / "_bundled" / "data", _PACKAGE.parent / "data"):
        if d.is_dir():
            return d
    raise ParameterError("cannot find dnarod's bundled data directory; reinstall dnarod")


def available_forcefields() -> list[str]:
    """Names of the bundled force fields."""
    names: set[str] = set()
    for d in SEARCH_DIRS:
        if d.is_dir():
            names.update(p.stem for p in d.glob("*.toml"))
    return sorted(names)


def quantity(table: dict[str, Any], key: str, dimension: str, where: str,
             shape: tuple[int, ...] | None = None) -> np.ndarray:
    """Read ``table[key] = {value, unit}`` and convert it to dnarod units."""
    if key not in table:
        raise ParameterError(f"{where}: missing entry '{key}' (a table {{ value = ..., unit = \"...\" }})")
    entry = table[key]
    if not isinstance(entry, dict) or "value" not in entry:
        raise ParameterError(f"{where}.{key}: must be a table {{ value = ..., unit = \"...\" }}, got {entry!r}")
    if "unit" not in entry:
        raise ParameterError(f"{where}.{key}: missing unit; give unit = \"...\" (for {dimension}, e.g. "
                             f"{', '.join(u for u, (d, _) in UNITS.items() if d == dimension)})")
    unit = entry["unit"]
    if unit not in UNITS or UNITS[unit][0] != dimension:
        ok = [u for u, (d, _) in UNITS.items() if d == dimension]
        raise ParameterError(f"{where}.{key}: unit {unit!r} is not a unit of {dimension}; use one of {ok}")
    try:
        value = np.asarray(entry["value"], dtype=float) * UNITS[unit][1]
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"{where}.{key}: value is not numeric ({exc})") from None
    if shape is not None and value.shape != shape:
        raise ParameterError(f"{where}.{key}: expected shape {shape}, got {value.shape}")
    if not np.isfinite(value).all():
        raise ParameterError(f"{where}.{key}: value is not finite")
    return value


#: Watson-Crick complement of a base letter (U pairs with A, inosine I with C): the one table of it.
COMPLEMENT = {"A": "T", "T": "A", "G": "C", "C": "G", "U": "A", "I": "C"}


def normalise_sequence(sequence: str, where: str = "sequence") -> str:
    """Upper-case DNA sequence (A, C, G, T); whitespace removed.

    Raises
    ------
    ParameterError
        Naming the position and letter of the first character that is not A, C, G or T.
    """
    if not isinstance(sequence, str):
        raise ParameterError(f"{where}: must be a string of A, C, G, T, got {type(sequence).__name__}")
    seq = "".join(sequence.split()).upper()
    for i, ch in enumerate(seq):
        if ch not in "ACGT":
            raise ParameterError(f"{where}: letter {ch!r} at position {i + 1} is not A, C, G or T "
                                 f"(map modified bases to their parent base first)")
    if len(seq) < 2:
        raise ParameterError(f"{where}: need at least 2 base pairs, got {len(seq)}")
    return seq


def sequence_steps(sequence: str, circular: bool = False) -> list[str]:
    """Dinucleotide step names along strand I, e.g. ``"ACG" -> ["AC", "CG"]`` (plus ``"GA"`` if circular)."""
    seq = normalise_sequence(sequence)
    steps = [seq[i:i + 2] for i in range(len(seq) - 1)]
    if circular:
        steps.append(seq[-1] + seq[0])
    return steps


@dataclass
class ForceField:
    """A loaded parameter set.

    Attributes
    ----------
    name : str
    kind : str
        ``"uniform"``, ``"sequence-3dna"`` or ``"material"``.
    ds : float
        Arc length per step, nm.
    node_mass : float
        amu.
    node_inertia : ndarray, shape (3,)
        Principal moments about d1, d2, d3, amu nm^2.
    temperature : float
        Temperature (K) at which thermal quantities (persistence lengths, kT-unit tables) were
        converted to stiffnesses.
    table : dict
        Per step type: ``(stiffness (6, 6), intrinsic (6,))``; a uniform set has the key ``"*"``.
    """

    name: str
    kind: str
    ds: float
    node_mass: float
    node_inertia: np.ndarray
    temperature: float
    table: dict[str, tuple[np.ndarray, np.ndarray]]
    description: str = ""
    sources: list[Any] = field(default_factory=list)
    path: str | None = None

    def step_parameters(self, sequence: str | None = None, circular: bool = False,
                        n_steps: int | None = None) -> StepParameters:
        """Per-step parameters for a sequence (strand I, 5'->3').

        Parameters
        ----------
        sequence : str, optional
            Required for sequence-dependent sets. For uniform sets give either a sequence
            (for step names) or ``n_steps``.
        circular : bool
            Add the closing step (last base, first base).
        n_steps : int, optional

        Returns
        -------
        StepParameters
        """
        if "*" in self.table:
            if sequence is not None:
                names = sequence_steps(sequence, circular)
            elif n_steps is not None:
                names = [self.name] * int(n_steps)
            else:
                raise ParameterError(f"force field {self.name}: give a sequence or n_steps")
            K, xi0 = self.table["*"]
            return StepParameters(np.repeat(K[None], len(names), 0), np.repeat(xi0[None], len(names), 0), names)
        if sequence is None:
            raise ParameterError(f"force field {self.name} is sequence dependent; give a sequence")
        names = sequence_steps(sequence, circular)
        missing = sorted({s for s in names if s not in self.table})
        if missing:
            raise ParameterError(f"force field {self.name}: unknown step type(s) {missing}; "
                                 f"it defines {sorted(self.table)}")
        return StepParameters(np.array([self.table[s][0] for s in names]),
                              np.array([self.table[s][1] for s in names]), names)

    def model_from_sequence(self, sequence: str | None = None, circular: bool = False,
                            n_nodes: int | None = None) -> RodModel:
        """A model at its intrinsic (zero-energy) shape.

        For a circular chain the screw closure is chosen so the intrinsic shape closes
        exactly (``S = g_N g_0^-1`` of the intrinsic chain); rings with another linking
        number are built by changing the closure rotation.

        Parameters
        ----------
        sequence : str, optional
            Strand I, 5'->3'. Uniform sets also accept ``n_nodes`` instead.
        circular : bool
        n_nodes : int, optional

        Returns
        -------
        RodModel
        """
        if sequence is not None:
            sequence = normalise_sequence(sequence)
            n = len(sequence)
        elif n_nodes is not None:
            n = int(n_nodes)
            if n < 2:
                raise ParameterError(f"n_nodes must be at least 2, got {n}")
        else:
            raise ParameterError("give a sequence or n_nodes")
        n_steps = n if circular else n - 1
        params = self.step_parameters(sequence, circular, n_steps=n_steps)
        pos, frm = chain_from_strains(params.Omega0, params.Gamma0, self.ds)
        closure = None
        if circular:
            closure = Closure(frm[-1], pos[-1])  # g_N g_0^-1 with g_0 = identity
            pos, frm = pos[:-1], frm[:-1]
        return RodModel(pos, frm, params, self.ds, np.full(n, self.node_mass),
                        np.tile(self.node_inertia, (n, 1)), closure=closure, sequence=sequence,
                        metadata={"forcefield": self.name})

    def ring(self, sequence: str | None = None, n_nodes: int | None = None, linking_number: int | None = None,
             delta_linking_number: int = 0) -> RodModel:
        """A planar closed ring (see :meth:`RodModel.ring`).

        Parameters
        ----------
        sequence : str, optional
            Strand I, 5'->3'; uniform sets also accept ``n_nodes``.
        linking_number : int, optional
            Default: the relaxed ``round(sum of intrinsic twists / 2 pi)`` plus ``delta_linking_number``.
        delta_linking_number : int
            Supercoiling relative to the relaxed ring (ignored if ``linking_number`` is given).
        """
        if sequence is not None:
            sequence = normalise_sequence(sequence)
            n = len(sequence)
        elif n_nodes is not None:
            n = int(n_nodes)
        else:
            raise ParameterError("give a sequence or n_nodes")
        params = self.step_parameters(sequence, circular=True, n_steps=n)
        if linking_number is None:
            turns = np.sum(2.0 * np.arctan(0.5 * self.ds * params.Omega0[:, 2])) / (2.0 * np.pi)
            linking_number = int(round(turns)) + int(delta_linking_number)
        return RodModel.ring(params, self.ds, np.full(n, self.node_mass), np.tile(self.node_inertia, (n, 1)),
                             linking_number, sequence=sequence)


def _node_block(doc, where):
    node = doc.get("node")
    if not isinstance(node, dict):
        raise ParameterError(f"{where}: missing [node] table with mass and inertia")
    mass = float(quantity(node, "mass", "mass", f"{where}[node]", shape=()))
    inertia = quantity(node, "inertia", "moment of inertia", f"{where}[node]", shape=(3,))
    if mass <= 0 or np.any(inertia <= 0):
        raise ParameterError(f"{where}[node]: mass and inertia must be positive")
    return mass, inertia


def _uniform_table(doc, where):
    st = doc.get("step")
    if not isinstance(st, dict):
        raise ParameterError(f"{where}: missing [step] table")
    return {"*": _step_table(st, f"{where}[step]")}


def _sequence_cayley_table(doc, where):
    steps = doc.get("steps")
    if not isinstance(steps, dict) or not steps:
        raise ParameterError(f"{where}: missing [steps.XY] tables (one per dinucleotide step type)")
    table = {}
    for name, st in steps.items():
        if len(name) != 2 or not set(name) <= set("ACGT") or not isinstance(st, dict):
            raise ParameterError(f"{where}: [steps.{name}] is not a dinucleotide step table (e.g. [steps.AC])")
        table[name] = _step_table(st, f"{where}[steps.{name}]")
    return table


def _step_table(st, w):
    """``(K (6, 6), xi0 (6,))`` from a table with Omega0, Gamma0, A, B, C."""
    A = quantity(st, "A", "energy*length", w, (3, 3))
    B = quantity(st, "B", "energy", w, (3, 3))
    C = quantity(st, "C", "energy/length", w, (3, 3))
    K = check_stiffness(np.block([[A, B], [B.T, C]]), name=f"{w} stiffness")
    xi0 = np.concatenate([quantity(st, "Omega0", "inverse length", w, (3,)),
                          quantity(st, "Gamma0", "dimensionless", w, (3,))])
    return K, xi0


def _read_csv(path, where):
    try:
        with open(path, newline="") as fh:
            return list(csv.DictReader(fh))
    except OSError as exc:
        raise ParameterError(f"{where}: cannot read {path} ({exc})") from None


def _sequence_3dna_table(doc, where, base, ds, temperature):
    src = doc.get("source")
    if not isinstance(src, dict) or "means" not in src or "force_constants" not in src:
        raise ParameterError(f"{where}: missing [source] with 'means' and 'force_constants' CSV files")
    if src.get("means_unit") != "A,deg" or src.get("force_constants_unit") != "kT":
        raise ParameterError(f"{where}[source]: means_unit must be \"A,deg\" and force_constants_unit \"kT\" "
                             f"(kT per Angstrom^2, per degree^2 and per Angstrom*degree)")
    order = ["shift", "slide", "rise", "tilt", "roll", "twist"]
    means = {}
    for row in _read_csv(base / src["means"], where):
        means[row["step"]] = np.array([float(row[c]) for c in
                                       ("shift_A", "slide_A", "rise_A", "tilt_deg", "roll_deg", "twist_deg")])
    consts: dict[str, np.ndarray] = {}
    for row in _read_csv(base / src["force_constants"], where):
        F = consts.setdefault(row["step"], np.full((6, 6), np.nan))
        F[order.index(row["row"])] = [float(row[c]) for c in order]
    kt = kT(temperature)
    table = {}
    for step, p0 in means.items():
        if step not in consts or np.isnan(consts[step]).any():
            raise ParameterError(f"{where}: step type {step} has means but no complete 6x6 force constants")
        F = check_stiffness(consts[step], name=f"{where} force constants of step {step}")
        xi0, K = stiffness_from_step_coordinates(p0, F, ds, kt)
        table[step] = (check_stiffness(K, name=f"{where} step {step}"), xi0)
    return table


# one argument per material constant of the rod (no defaults: each is a property of the material)
def material_rod_table(young_modulus: float, shear_modulus: float, radius: float, density: float,
                       shear_coefficient: float, ds: float, Omega0: np.ndarray,
                       Gamma0: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """Stiffness, node mass and inertia of a uniform solid circular rod.

    Parameters
    ----------
    young_modulus, shear_modulus : float
        kJ/mol/nm^3.
    radius : float
        nm.
    density : float
        amu/nm^3.
    shear_coefficient : float
        Timoshenko shear coefficient (6(1+nu)/(7+6nu) for a solid circle).
    ds : float
        nm.
    Omega0 : array (3,), 1/nm;  Gamma0 : array (3,)

    Returns
    -------
    K : (6, 6); xi0 : (6,); mass : float (amu); inertia : (3,) amu nm^2
        ``A = diag(E I, E I, G J)``, ``C = diag(k G a, k G a, E a)`` with area ``a = pi r^2``,
        ``I = pi r^4 / 4``, ``J = 2 I``; a node is a disc slice of length ds: mass ``rho a ds``,
        inertia ``rho ds (I, I, 2 I)`` (planar, as the OpenMM triangle requires).
    """
    area = np.pi * radius**2
    I = np.pi * radius**4 / 4
    A = np.diag([young_modulus * I, young_modulus * I, shear_modulus * 2 * I])
    C = np.diag([shear_coefficient * shear_modulus * area] * 2 + [young_modulus * area])
    K = np.block([[A, np.zeros((3, 3))], [np.zeros((3, 3)), C]])
    xi0 = np.concatenate([Omega0, Gamma0])
    return K, xi0, density * area * ds, density * ds * np.array([I, I, 2 * I])


def load_forcefield(name_or_path: str | Path) -> ForceField:
    """Load a force field by bundled name (see :func:`available_forcefields`) or file path.

    Raises
    ------
    ParameterError
        Unknown name, unreadable file, or a schema error naming the entry.
    """
    p = Path(name_or_path)
    if not p.suffix:
        for d in SEARCH_DIRS:
            if (d / f"{name_or_path}.toml").is_file():
                p = d / f"{name_or_path}.toml"
                break
        else:
            raise ParameterError(f"unknown force field {name_or_path!r}; bundled: {available_forcefields()}, "
                                 f"or give a path to a .toml file")
    where = p.name
    try:
        doc = tomllib.loads(p.read_text())
    except IsADirectoryError:
        raise ParameterError(f"{p}: a folder, not a force-field .toml file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ParameterError(f"{p}: cannot read force field ({type(exc).__name__}: not a TOML text file?)") from None
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError(f"{p}: not valid TOML ({exc})") from None
    kind = doc.get("kind")
    temperature = float(quantity(doc, "temperature", "temperature", where, shape=())) if "temperature" in doc else 300.0
    if kind == "uniform":
        table = _uniform_table(doc, where)
        ds = float(quantity(doc["step"], "ds", "length", f"{where}[step]", ()))
        mass, inertia = _node_block(doc, where)
    elif kind == "sequence-cayley":
        ds = float(quantity(doc.get("step", {}), "ds", "length", f"{where}[step]", ()))
        table = _sequence_cayley_table(doc, where)
        mass, inertia = _node_block(doc, where)
    elif kind == "sequence-3dna":
        ds = float(quantity(doc.get("step", {}), "ds", "length", f"{where}[step]", ()))
        table = _sequence_3dna_table(doc, where, _data_base(p), ds, temperature)
        mass, inertia = _node_block(doc, where)
    elif kind == "material":
        mat = doc.get("material", {})
        w = f"{where}[material]"
        st = doc.get("step", {})
        ds = float(quantity(st, "ds", "length", f"{where}[step]", ()))
        K, xi0, mass, inertia = material_rod_table(
            float(quantity(mat, "young_modulus", "pressure", w, ())),
            float(quantity(mat, "shear_modulus", "pressure", w, ())),
            float(quantity(mat, "radius", "length", w, ())),
            float(quantity(mat, "density", "density", w, ())),
            float(quantity(mat, "shear_coefficient", "dimensionless", w, ())), ds,
            quantity(st, "Omega0", "inverse length", f"{where}[step]", (3,)),
            quantity(st, "Gamma0", "dimensionless", f"{where}[step]", (3,)))
        table = {"*": (check_stiffness(K, name=f"{where} stiffness"), xi0)}
    else:
        raise ParameterError(f"{where}: kind must be 'uniform', 'sequence-cayley', 'sequence-3dna' or 'material', "
                             f"got {kind!r}")
    if not ds > 0:
        raise ParameterError(f"{where}[step].ds must be positive, got {ds}")
    return ForceField(name=doc.get("name", p.stem), kind=kind, ds=ds, node_mass=mass, node_inertia=inertia,
                      temperature=temperature, table=table, description=doc.get("description", ""),
                      sources=list(doc.get("sources", [])), path=str(p))


def _data_base(ff_path):
    """Directory that a force field's relative data paths are relative to (the bundled data dir)."""
    candidates = [ff_path.parent.parent / "data", ff_path.parent / "data"]
    for c in candidates:
        if c.is_dir():
            return c
    return data_dir()


def _toml_str(text):
    return '"' + str(text).replace("\\", "\\\\").replace('"', '\\"') + '"'


# one argument per entry of the force-field file
def write_forcefield(path: str | Path, name: str, table: dict[str, tuple[np.ndarray, np.ndarray]], ds: float,
                     node_mass: float, node_inertia: np.ndarray, temperature: float = 300.0, description: str = "",
                     sources: tuple[Any, ...] | list[Any] = (), header: str = "") -> None:
    """Write a force field file that :func:`load_forcefield` reads (atomically).

    Parameters
    ----------
    path : str or Path
    name : str
    table : dict
        ``{"*": (K, xi0)}`` writes ``kind = "uniform"``; dinucleotide keys ``{"AC": (K, xi0), ...}``
        write ``kind = "sequence-cayley"``. K (6, 6) in kJ/mol units, xi0 (6,) as (Omega0 1/nm, Gamma0).
    ds : float
        nm.
    node_mass : float
        amu.
    node_inertia : array (3,)
        amu nm^2.
    temperature : float
        K.
    description : str
    sources : sequence of str
    header : str
        Comment lines put at the top of the file.
    """
    def num(v):
        return f"{float(v):.12g}"
    def vec(v):
        return "[" + ", ".join(num(x) for x in v) + "]"
    def mat(M):
        return "[" + ", ".join(vec(r) for r in M) + "]"

    def block(K, xi0):
        K, xi0 = check_stiffness(K, name=f"{name}"), np.asarray(xi0, float)
        return [f'Omega0 = {{ value = {vec(xi0[:3])}, unit = "1/nm" }}',
                f'Gamma0 = {{ value = {vec(xi0[3:])}, unit = "1" }}',
                f'A = {{ value = {mat(K[:3, :3])}, unit = "kJ/mol*nm" }}',
                f'B = {{ value = {mat(K[:3, 3:])}, unit = "kJ/mol" }}',
                f'C = {{ value = {mat(K[3:, 3:])}, unit = "kJ/mol/nm" }}']

    uniform = set(table) == {"*"}
    lines = [f"# {line}" for line in header.splitlines()] + [
        f"name = {_toml_str(name)}", f'kind = "{"uniform" if uniform else "sequence-cayley"}"',
        f"description = {_toml_str(description)}", f'temperature = {{ value = {num(temperature)}, unit = "K" }}',
        "sources = [" + ", ".join(_toml_str(s) for s in sources) + "]", "",
        "[step]", f'ds = {{ value = {num(ds)}, unit = "nm" }}']
    if uniform:
        lines += block(*table["*"])
    else:
        for step in sorted(table):
            lines += ["", f"[steps.{step}]"] + block(*table[step])
    lines += ["", "[node]", f'mass = {{ value = {num(node_mass)}, unit = "amu" }}',
              f'inertia = {{ value = {vec(node_inertia)}, unit = "amu*nm^2" }}', ""]
    write_text_atomic(path, "\n".join(lines))
