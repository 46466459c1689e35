"""A chemically valid all-atom duplex from base-pair (node) frames, ready for MD.

Three stages:

1. **Placement** (:func:`dnarod.structure.rebuild.rebuild_coordinates`): each base is the
   standard base (Olson et al. 2001) in the base frame that the pair frame and the six pair
   parameters give; each nucleotide's sugar-phosphate is the B-DNA fibre template carried
   rigidly with its base. Exact for ideal B-DNA; elsewhere the O3'(i)-P(i+1) links are
   stretched or compressed (0.2-3.9 A on crystal frames).
2. **Backbone closure**: the duplex is parametrised with OpenMM's Amber14 DNA force field
   (``amber14/DNA.OL15.xml``: OL15 on parmbsc0/parm99) in OBC2 implicit solvent (Amber igb=5
   radii and screening, OpenMM's native ``GBSAOBCForce`` with the parameters of
   ``implicit/obc2.xml``), hydrogens are added by ``Modeller.addHydrogens``, every base ring
   atom (the atoms the base frame is fitted to) is held by a harmonic restraint. The closure starts
   from the fibre steps, where the template's backbone is nearly closed, and follows a path of
   intermediate frames to the input's (:func:`_homotopy`), so the backbone is carried along rather
   than untangled from a far-off start: covalent terms with a capped repulsion first, then the
   full force field (1.2 nm non-periodic cut-off: the closure is a local fit, and a cut-off keeps
   it linear in length) at each stage with soft restraints, firm ones on the input frames, and a
   polish with the covalent terms (bond constants x ``POLISH_BOND_SCALE``), repulsion and
   firm restraints only (why: see ``POLISH_BOND_SCALE``). Before each stage the
   targets are the bases' current, force-field-relaxed shape refitted onto the exact placed frames
   (:func:`_retarget`), so holding a frame does not strain its ring bonds.
3. **Windows** (duplexes longer than ``WINDOW_CORE + 2 * WINDOW_FLANK`` bp): the closure (2) is run on
   overlapping windows, each a core of ``WINDOW_CORE`` bp with ``WINDOW_FLANK`` bp on each side,
   every window built and closed as a duplex of its own (its own fibre-to-input path); each atom is
   taken from the window whose core holds its base pair, and the whole duplex is then polished as in
   the closure's last step (covalent terms, stiffened bonds, firm restraints) with a capped iteration count, which brings the links where two cores meet to Amber14's
   lengths. Each window costs the same whatever the length, so the rebuild is linear in length (one
   closure of the whole grew faster: 0.6 s CPU per bp at 12 bp, 1.0 at 24, over 11 at 147).

Before the closure, frames that put ring atoms of two bases closer than any placement within the
frame tolerance could separate to 2.2 A are refused at once (:func:`_placed_clash`), naming the
atoms, the step, the distance and the shortfall.

Checked after the closure (:class:`RebuildReport`): every covalent bond's deviation from its
Amber14 equilibrium length, the shortest distance between heavy atoms that are neither bonded
nor share a bonded neighbour, the base-pair frames refitted from the atoms against the input
(origin distance and rotation angle), and sugar chirality (C1', C3', C4' as in the template).
A backbone that does not close (a bond still more than ``bond_tolerance`` off, e.g. when two
frames are too far apart) raises :class:`~dnarod.core.errors.StructureError` naming the step and
the length; a base pair moved by more than 0.05 A or 1 degree raises one naming the pair.

Units: nm, kJ/mol inside; files in Angstrom (PDB) through OpenMM's writers.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from dnarod.core.errors import StructureError
from dnarod.structure.frames import standard_bases
from dnarod.structure.rebuild import fibre_pair_parameters, rebuild_coordinates

_log = logging.getLogger(__name__)

FORCEFIELD_FILES = ("amber14/DNA.OL15.xml",)
RESTRAINT_K = 2.0e5        # kJ/mol/nm^2 on each base ring atom (final, firm)
RESTRAINT_SCHEDULE = (2.0e4,)  # kJ/mol/nm^2: softer stages before the final firm one
HOMOTOPY = (0.0, 0.25, 0.5, 0.75, 1.0)  # fractions of the way from the fibre steps to the input's
FIBRE_RISE = 0.338         # nm, B-DNA fibre (Chandrasekaran & Arnott; 3DNA fibre model 4)
FIBRE_TWIST = np.radians(36.0)
FRAME_ORIGIN_TOL = 0.005   # nm: largest accepted shift of a base-pair origin
FRAME_ANGLE_TOL = 1.0      # degrees: largest accepted rotation of a base-pair frame
MIN_CUTOFF = 1.2           # nm, non-bonded cut-off during the closure (local geometry only)
EXTRA_ROUNDS = 3           # minimiser restarts while a bond is still off
CHIRAL_K = 1.0e3           # kJ/mol/rad^2, flat-bottom restraint on sugar stereocentres
BOND_TOLERANCE = 0.005     # nm: largest accepted deviation of a bond from its Amber14 equilibrium
# Bond force constants are multiplied by this in the final polish. Why: the residual strain that
# the frames leave in a nucleotide sits mostly in the angles at C1' (C2'-C1'-N opened by 5-10 deg, already
# 5.6 deg on average at the full Amber14 minimum of ideal B-DNA, where bonds are up to 0.04 A off their
# equilibrium); with Amber's own bond/angle stiffness part of that strain stretches the glycosidic bond to
# 0.03-0.05 A (and the Watson-Crick hydrogen bonds stretch the amino C-N bonds by up to 0.04 A). Softening
# the base restraints does not relieve it (4x softer: frames move 3x more, the bond 0.0015 A less), more
# minimiser iterations do not either; stiffer bonds move it into the angles (largest angle deviation reported,
# unchanged within 0.3 deg on 355D and a thermal snapshot).
POLISH_BOND_SCALE = 4.0
RING_SLACK = 0.005         # nm: ring atoms' allowed departure from the rigid standard base (refitted shape)
# Windows. Why: one closure of the whole duplex costs more than linearly in its length (L-BFGS needs more
# iterations as the system grows, and the fibre-to-input path moves a long, bent duplex far), 0.6 s CPU
# per bp at 12 bp, 1.0 at 24 and more than 11 at 147; closing overlapping windows of a fixed size and
# polishing the whole briefly makes the cost linear in length.
WINDOW_CORE = 12           # bp whose atoms each window's closure keeps
WINDOW_FLANK = 4           # bp closed on each side of a core and discarded (1.35 nm, beyond MIN_CUTOFF)
POLISH_ITERATIONS = 1000   # L-BFGS iterations per round of the global polish after the windows
MIN_NONBONDED = 0.22       # nm: shortest accepted heavy-atom distance beyond 1-3 neighbours
SUGAR_CHIRAL = (("C1'", "O4'", "C2'", "N"), ("C3'", "C4'", "C2'", "O3'"), ("C4'", "O4'", "C3'", "C5'"))


@dataclass
class RebuildReport:
    """Geometry of a rebuilt duplex (lengths in nm, angles in degrees).

    Attributes
    ----------
    max_bond_deviation : float
        Largest |length - Amber14 equilibrium| over all covalent bonds, nm.
    worst_bond : str
        That bond, named by residues and atoms.
    o3p_range : tuple of float
        Shortest and longest O3'(i)-P(i+1) link, nm.
    o3p_equilibrium : float
        Amber14's O3'-P equilibrium length, nm.
    min_nonbonded : float
        Shortest heavy-atom distance between atoms neither bonded nor sharing a neighbour, nm.
    min_nonbonded_pair : str
    frame_origin_error : float
        Largest distance between input and refitted base-pair origins, nm.
    frame_angle_error : float
        Largest rotation between input and refitted base-pair frames, degrees.
    placement_o3p_range : tuple of float
        O3'-P link lengths before the closure, nm.
    max_angle_deviation : float
        Largest |angle - Amber14 equilibrium| over all bond angles, degrees.
    worst_angle : str
    energy : float
        Final potential energy (restraints excluded), kJ/mol.
    seconds : float
        Wall time of the closure.
    cpu_seconds : float
    """

    max_bond_deviation: float
    worst_bond: str
    o3p_range: tuple
    o3p_equilibrium: float
    min_nonbonded: float
    min_nonbonded_pair: str
    frame_origin_error: float
    frame_angle_error: float
    placement_o3p_range: tuple
    energy: float
    seconds: float
    cpu_seconds: float
    max_angle_deviation: float = float("nan")
    worst_angle: str = ""

    def summary(self):
        """Readable lines (Angstrom and degrees)."""
        return [
            f"bonds: largest deviation from Amber14 equilibrium {10 * self.max_bond_deviation:.3f} A "
            f"({self.worst_bond})",
            f"O3'-P: {10 * self.o3p_range[0]:.3f}-{10 * self.o3p_range[1]:.3f} A (Amber14 "
            f"{10 * self.o3p_equilibrium:.3f} A; before closure {10 * self.placement_o3p_range[0]:.2f}-"
            f"{10 * self.placement_o3p_range[1]:.2f} A)",
            f"angles: largest deviation from Amber14 equilibrium {self.max_angle_deviation:.1f} deg "
            f"({self.worst_angle})",
            f"closest non-bonded heavy atoms: {10 * self.min_nonbonded:.2f} A ({self.min_nonbonded_pair})",
            f"base-pair frames kept within {10 * self.frame_origin_error:.4f} A and {self.frame_angle_error:.4f} deg",
            f"energy {self.energy:.1f} kJ/mol; closure {self.seconds:.2f} s wall, {self.cpu_seconds:.2f} s CPU",
        ]


@dataclass
class AllAtomDuplex:
    """A rebuilt duplex: OpenMM topology and positions (with or without hydrogens).

    Attributes
    ----------
    topology : openmm.app.Topology
    positions : ndarray, shape (n_atoms, 3)
        nm.
    report : RebuildReport
    """

    topology: object
    positions: np.ndarray
    report: RebuildReport
    notes: list = field(default_factory=list)

    def write(self, path, hydrogens=True):
        """Write PDB (``.pdb``) or PDBx/mmCIF (``.cif``) atomically; hydrogens optional."""
        write_allatom(path, self.topology, self.positions, hydrogens=hydrogens)


def _topology(atoms, xyz):
    """OpenMM topology with standard (residues.xml) bonds from the placement's atom list."""
    import openmm.app as app

    top = app.Topology()
    chains, res, key = {}, None, None
    for chain, num, rname, aname, el in atoms:
        if chain not in chains:
            chains[chain] = top.addChain(chain)
        if (chain, num) != key:
            res = top.addResidue(rname, chains[chain], id=str(num))
            key = (chain, num)
        top.addAtom(aname, app.Element.getBySymbol(el), res)
    top.createStandardBonds()
    return top


@lru_cache(maxsize=1)
def _amber_forcefield():
    """OpenMM's Amber14 DNA force field (parsed once: every window of a long rebuild uses it twice)."""
    import openmm.app as app

    return app.ForceField(*FORCEFIELD_FILES)


def amber_md_simulation(pdb, cutoff=None, seed=7):
    """An OpenMM ``Simulation`` of a rebuilt (or any) DNA file: Amber14 + OBC2, ready to run MD.

    Amber14 (``amber14-all.xml`` + ``implicit/obc2.xml``) with H bonds constrained, its OBC2 term as the native
    GBSAOBCForce (:func:`_add_obc2`: the same model, much faster), Langevin middle 300 K, 1/ps, 2 fs, CPU
    platform; positions from the file, velocities drawn at 300 K with ``seed``.

    Parameters
    ----------
    pdb : openmm.app.PDBFile
    cutoff : float, optional
        Non-periodic cut-off, nm (default: none, every pair).
    seed : int

    Returns
    -------
    openmm.app.Simulation
    """
    import openmm
    import openmm.app as app
    import openmm.unit as u

    ff = app.ForceField("amber14-all.xml", "implicit/obc2.xml")
    if cutoff is None:
        system = ff.createSystem(pdb.topology, nonbondedMethod=app.NoCutoff, constraints=app.HBonds)
    else:
        system = ff.createSystem(pdb.topology, nonbondedMethod=app.CutoffNonPeriodic, constraints=app.HBonds,
                                 nonbondedCutoff=cutoff * u.nanometer)
    for k in reversed(range(system.getNumForces())):
        if isinstance(system.getForce(k), openmm.CustomGBForce):
            system.removeForce(k)
    _add_obc2(system, pdb.topology)
    integ = openmm.LangevinMiddleIntegrator(300 * u.kelvin, 1 / u.picosecond, 2 * u.femtosecond)
    integ.setRandomNumberSeed(seed)
    sim = app.Simulation(pdb.topology, system, integ, openmm.Platform.getPlatformByName("CPU"))
    sim.context.setPositions(pdb.positions)
    sim.context.setVelocitiesToTemperature(300 * u.kelvin, seed)
    return sim


def _add_obc2(system, topology):
    """OBC2 implicit solvent as OpenMM's native GBSAOBCForce (Amber igb=5 parameters).

    ``implicit/obc2.xml`` builds the same model as a CustomGBForce, tens of times slower on
    the CPU platform; the parameters are OpenMM's own (``GBSAOBC2Force.getStandardParameters``).
    """
    import openmm
    from openmm.app.internal.customgbforces import GBSAOBC2Force

    nb = [f for f in system.getForces() if isinstance(f, openmm.NonbondedForce)][0]
    gb = openmm.GBSAOBCForce()
    gb.setSolventDielectric(78.5)
    gb.setSoluteDielectric(1.0)
    if nb.getNonbondedMethod() == openmm.NonbondedForce.NoCutoff:
        gb.setNonbondedMethod(openmm.GBSAOBCForce.NoCutoff)
    else:
        gb.setNonbondedMethod(openmm.GBSAOBCForce.CutoffNonPeriodic)
        gb.setCutoffDistance(nb.getCutoffDistance())
    for i, (radius, scale) in enumerate(GBSAOBC2Force.getStandardParameters(topology)):
        gb.addParticle(nb.getParticleParameters(i)[0], radius, scale)
    system.addForce(gb)
    return gb


def amber_system(topology, constraints=None, cutoff=None):
    """Amber14 (OL15) DNA in OBC2 implicit solvent: ``(openmm.System, ForceField)``.

    ``cutoff`` (nm): None for no cut-off, else a non-periodic cut-off (reaction field) for
    the Coulomb, Lennard-Jones and GB terms.
    """
    import openmm
    import openmm.app as app

    ff = _amber_forcefield()
    try:
        if cutoff is None:
            system = ff.createSystem(topology, nonbondedMethod=app.NoCutoff, constraints=constraints)
        else:
            system = ff.createSystem(topology, nonbondedMethod=app.CutoffNonPeriodic, constraints=constraints,
                                     nonbondedCutoff=cutoff * openmm.unit.nanometer)
    except ValueError as exc:
        raise StructureError(f"rebuild: Amber14 does not accept the rebuilt topology: {exc}") from None
    _add_obc2(system, topology)
    return system, ff


def _bond_table(system, topology):
    import openmm

    hb = [f for f in system.getForces() if isinstance(f, openmm.HarmonicBondForce)][0]
    out = []
    for k in range(hb.getNumBonds()):
        i, j, r0, _ = hb.getBondParameters(k)
        out.append((i, j, r0.value_in_unit(r0.unit)))
    return np.array([(i, j) for i, j, _ in out], int), np.array([r for *_, r in out])


def _atom_name(atom):
    r = atom.residue
    return f"{r.chain.id}:{r.id}{r.name[-1]} {atom.name}"


def _restrain(system, topology, positions, k):
    """Harmonic restraints on each base's ring atoms (the atoms the base frame is fitted to).

    Returns the force and, per residue, ``(atom indices, standard-base coordinates)`` in the
    order of the restraint's particles, for :func:`_retarget`.
    """
    import openmm

    std, ring = standard_bases()
    f = openmm.CustomExternalForce("0.5*kr*((x-x0)^2+(y-y0)^2+(z-z0)^2)")
    f.addGlobalParameter("kr", k)
    for name in ("x0", "y0", "z0"):
        f.addPerParticleParameter(name)
    groups = []
    for res in topology.residues():
        letter = res.name[-1]
        idx = {a.name: a.index for a in res.atoms()}
        names = [a for a in ring.get(letter, ()) if a in idx]
        if len(names) < 3:
            continue
        ids = np.array([idx[a] for a in names])
        for i in ids:
            f.addParticle(int(i), list(map(float, positions[i])))
        groups.append((ids, np.array([std[letter][a] for a in names])))
    f.setForceGroup(31)
    system.addForce(f)
    return f, groups


def _retarget(force, context, groups, pos, placed):
    """Move each base's restraint targets to its current (relaxed) shape, refitted onto its placed frame.

    The target of base b is ``o_in + R_in R_b^T (x - o_b)`` where ``(R_b, o_b)`` is the standard-base
    fit of its current ring atoms ``x`` and ``(R_in, o_in)`` the fit of the placed ones: the fitted
    frame of the targets is the placed frame exactly (the fit is equivariant under rigid motions),
    while their internal geometry is the force field's, so firm restraints hold the frame without
    straining the ring bonds toward the standard base's lengths.
    """
    from dnarod.structure.frames import kabsch

    k = 0
    for ids, ref in groups:
        Rb, ob, _ = kabsch(ref, pos[ids])
        Ri, oi, _ = kabsch(ref, placed[ids])
        tgt = (pos[ids] - ob) @ Rb @ Ri.T + oi
        for i, x in zip(ids, tgt):
            force.setParticleParameters(k, int(i), list(map(float, x)))
            k += 1
    force.updateParametersInContext(context)


def _sugar_stereocentres(topology):
    """Yield ``(residue index, centre name, (centre, a, b, c) atom indices)`` for every sugar stereocentre of
    ``SUGAR_CHIRAL`` present in ``topology`` (``N`` is the glycosidic N9 of purines, N1 of pyrimidines)."""
    for res in topology.residues():
        idx = {a.name: a.index for a in res.atoms()}
        for centre, a, b, c in SUGAR_CHIRAL:
            if c == "N":
                c = "N9" if "N9" in idx else "N1"
            if all(x in idx for x in (centre, a, b, c)):
                yield res.index, centre, (idx[centre], idx[a], idx[b], idx[c])


def _hold_chirality(system, topology, positions, k=CHIRAL_K):
    """Flat-bottom restraints that keep each sugar stereocentre's improper dihedral on its side.

    Zero energy while the improper keeps the sign it has in the template (so no bias on the
    geometry); ``k * theta^2`` once it crosses. Without them a steep start (overlapping atoms
    from the rigid placement) can invert a sugar during minimisation.
    """
    import openmm

    f = openmm.CustomTorsionForce("kc*min(0, s*theta)^2")
    f.addGlobalParameter("kc", k)
    f.addPerTorsionParameter("s")
    for _, _, (i_centre, i_a, i_b, i_c) in _sugar_stereocentres(topology):
        q = [i_a, i_b, i_centre, i_c]
        x = positions[q]
        b0, b1, b2 = x[1] - x[0], x[2] - x[1], x[3] - x[2]
        n1, n2 = np.cross(b0, b1), np.cross(b1, b2)
        sign = np.sign(np.dot(np.cross(n1, n2), b1)) or 1.0
        f.addTorsion(*q, [float(sign)])
    f.setForceGroup(31)
    system.addForce(f)


def _scale_bonds(system, factor, context=None):
    """Multiply every HarmonicBondForce constant of ``system`` by ``factor`` (and update ``context``)."""
    import openmm

    for f in system.getForces():
        if isinstance(f, openmm.HarmonicBondForce):
            for k in range(f.getNumBonds()):
                i, j, r0, kb = f.getBondParameters(k)
                f.setBondParameters(k, i, j, r0, kb * factor)
            if context is not None:
                f.updateParametersInContext(context)


def _pair_of(residue, n):
    """Base-pair index (1-based) of a residue of the rebuilt duplex (chain A: 1..n, chain B: n+1..2n)."""
    r = int(residue.id) if hasattr(residue, "id") else int(residue)
    return r if r <= n else 2 * n + 1 - r


def _where(k, l):
    """``step 4-5`` for neighbouring pairs, else ``base pairs 4 and 9``."""
    a, b = sorted((k, l))
    return f"step {a}-{b}" if b == a + 1 else (f"base pair {a}" if a == b else f"base pairs {a} and {b}")


def _placed_clash(xyz, atoms, F, O, n):
    """Refuse frames that put base ring atoms of two nucleotides into each other beyond any fix.

    ``xyz`` (nm) and ``atoms`` are the rigid placement on the input frames. A ring atom at distance
    rho from its pair's origin moves by at most ``FRAME_ORIGIN_TOL + 2 rho sin(FRAME_ANGLE_TOL / 2)``
    while its pair frame stays within the accepted tolerance (bases rigid in the pair frame, as the
    pair parameters are kept) plus ``RING_SLACK`` for the ring's own shape, so two ring atoms placed
    at d can end at most ``d`` plus both moves apart. If that is still under ``MIN_NONBONDED``, no
    backbone closure can pass the checks: raise before minimising, naming the atoms and the step.
    """
    from scipy.spatial import cKDTree

    _, ring = standard_bases()
    names = {a for r in ring.values() for a in r}
    keep = np.array([i for i, a in enumerate(atoms) if a[3] in names])
    if len(keep) == 0:
        return
    res = np.array([(0 if atoms[i][0] == "A" else 1) * 100000 + atoms[i][1] for i in keep])
    pair = np.array([_pair_of(atoms[i][1], n) - 1 for i in keep])
    x = xyz[keep]
    rho = np.linalg.norm(x - O[pair], axis=1)
    move = FRAME_ORIGIN_TOL + 2 * rho * np.sin(np.radians(FRAME_ANGLE_TOL) / 2) + RING_SLACK
    worst = None
    for i, j in cKDTree(x).query_pairs(MIN_NONBONDED):
        if res[i] == res[j]:
            continue
        d = np.linalg.norm(x[i] - x[j])
        reach = d + move[i] + move[j]
        if reach < MIN_NONBONDED and (worst is None or d < worst[0]):
            worst = (d, reach, i, j)
    if worst is None:
        return
    d, reach, i, j = worst
    a, b = atoms[keep[i]], atoms[keep[j]]
    name = lambda t: f"{t[0]}:{t[1]}{t[2][-1]} {t[3]}"  # noqa: E731
    raise StructureError(
        f"rebuild: the input frames put ring atoms {name(a)} and {name(b)} ({_where(pair[i] + 1, pair[j] + 1)}) "
        f"{10 * d:.2f} A apart; with each base pair kept within {10 * FRAME_ORIGIN_TOL:.2f} A and "
        f"{FRAME_ANGLE_TOL:.0f} deg of its frame they can be at most {10 * reach:.2f} A apart, "
        f"{10 * (MIN_NONBONDED - reach):.2f} A short of the {10 * MIN_NONBONDED:.1f} A clash limit: no backbone "
        f"closure can fix this (the two bases overlap); the input frames must put them at least "
        f"{10 * (MIN_NONBONDED - reach):.2f} A further apart")


# Amber14 (OL15/parm99 OS-P) O3'-P equilibrium length, nm (the report measures it from the force field: 1.610 A)
O3P_EQUILIBRIUM = 0.1610
_GAP_PATH_3 = ("N", "C1'", "C2'", "C3'", "O3'")          # from the base of nucleotide i to its O3'
_GAP_PATH_5 = ("P", "O5'", "C5'", "C4'", "O4'", "C1'", "N")  # from the P of nucleotide i+1 to its base


def _placed_gap(xyz, atoms, O, n, bond_tolerance):
    """Refuse frames that put two successive nucleotides of a strand further apart than any backbone reaches.

    The glycosidic N (N9 of purines, N1 of pyrimidines) of each base is a ring atom, held with its pair
    frame: it moves at most ``FRAME_ORIGIN_TOL + 2 rho sin(FRAME_ANGLE_TOL / 2) + RING_SLACK`` (see
    :func:`_placed_clash`). The shortest covalent path between the N atoms of nucleotides i and i+1 of a
    strand is N-C1'-C2'-C3'-O3'-P-O5'-C5'-C4'-O4'-C1'-N (11 bonds); with every bond within
    ``bond_tolerance`` of its length (the template's, O3'-P Amber14's) the two N atoms can be at most the
    sum of those lengths apart. If the frames put them further apart even after both moves, no closure
    can pass the checks: raise before minimising, naming the step, the distance and the shortfall.
    """
    from dnarod.structure.rebuild import nucleotide_template

    def path_length(letter, names):
        tn, tx = nucleotide_template(letter)
        ix = {a: i for i, a in enumerate(tn)}
        gly = "N9" if "N9" in ix else "N1"
        pts = [tx[ix[gly if a == "N" else a]] for a in names]
        return float(sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)))

    res = {}
    for i, (chain, num, rname, aname, _) in enumerate(atoms):
        res.setdefault((chain, num), {"letter": rname[-1]})[aname] = i
    worst = None
    for (chain, num), r in res.items():
        nxt = res.get((chain, num + 1))
        if nxt is None:
            continue
        g1 = r.get("N9", r.get("N1"))
        g2 = nxt.get("N9", nxt.get("N1"))
        k1, k2 = _pair_of(num, n) - 1, _pair_of(num + 1, n) - 1
        move = [FRAME_ORIGIN_TOL + 2 * np.linalg.norm(xyz[g] - O[k]) * np.sin(np.radians(FRAME_ANGLE_TOL) / 2)
                + RING_SLACK for g, k in ((g1, k1), (g2, k2))]
        span = (path_length(r["letter"], _GAP_PATH_3) + O3P_EQUILIBRIUM + path_length(nxt["letter"], _GAP_PATH_5)
                + 11 * bond_tolerance)
        d = float(np.linalg.norm(xyz[g1] - xyz[g2]))
        short = d - sum(move) - span
        if short > 0 and (worst is None or short > worst[0]):
            worst = (short, d, span, sum(move), chain, num, min(k1, k2) + 1)
    if worst is None:
        return
    short, d, span, move, chain, num, step = worst
    raise StructureError(
        f"rebuild: cannot close the backbone at step {step}-{step + 1} (strand {'I' if chain == 'A' else 'II'}, "
        f"{chain}:{num} - {chain}:{num + 1}): the input frames put their glycosidic N atoms {10 * d:.2f} A apart; "
        f"the sugar-phosphate path between them (11 bonds, each within {10 * bond_tolerance:.2f} A of its length) "
        f"spans at most {10 * span:.2f} A, {10 * (move):.2f} A more with both pairs moved by the frame tolerance: "
        f"{10 * short:.2f} A too far for any backbone; the frames must bring the two pairs that much closer")


def _soft_repulsion(system, topology, bonds):
    """A capped repulsion between atoms beyond 1-4 neighbours, for the covalent-only stage."""
    import openmm

    f = openmm.CustomNonbondedForce("ks*step(rc-r)*(rc-r)^2")
    f.addGlobalParameter("ks", 1.0e4)
    f.addGlobalParameter("rc", 0.25)
    for _ in range(system.getNumParticles()):
        f.addParticle([])
    f.createExclusionsFromBonds([(int(i), int(j)) for i, j in bonds], 3)
    f.setNonbondedMethod(openmm.CustomNonbondedForce.CutoffNonPeriodic)
    f.setCutoffDistance(0.3)
    system.addForce(f)


def _context(system, positions, platform):
    import openmm

    plat = openmm.Platform.getPlatformByName(platform or "CPU")
    ctx = openmm.Context(system, openmm.VerletIntegrator(0.001), plat)
    ctx.setPositions(positions)
    return ctx


def _relax(ctx, tolerance, iterations):
    """Minimise in ``ctx``: (positions nm, energy kJ/mol without the restraints)."""
    import openmm
    import openmm.unit as u

    openmm.LocalEnergyMinimizer.minimize(ctx, tolerance, iterations)
    st = ctx.getState(getPositions=True, getEnergy=True, groups={g for g in range(31)})
    return (np.array(st.getPositions(asNumpy=True).value_in_unit(u.nanometer)),
            st.getPotentialEnergy().value_in_unit(u.kilojoule_per_mole))


def _minimise(system, positions, tolerance, iterations, platform):
    import openmm
    import openmm.unit as u

    integ = openmm.VerletIntegrator(0.001)
    plat = openmm.Platform.getPlatformByName(platform) if platform else openmm.Platform.getPlatformByName("CPU")
    ctx = openmm.Context(system, integ, plat)
    ctx.setPositions(positions)
    openmm.LocalEnergyMinimizer.minimize(ctx, tolerance, iterations)
    st = ctx.getState(getPositions=True, getEnergy=True, groups={g for g in range(31)})
    pos = st.getPositions(asNumpy=True).value_in_unit(u.nanometer)
    energy = st.getPotentialEnergy().value_in_unit(u.kilojoule_per_mole)
    del ctx
    return np.array(pos), energy


def _angle_deviation(system, pos, atoms):
    """Largest |angle - Amber14 equilibrium| (degrees) over the system's HarmonicAngleForce, and which."""
    import openmm

    f = [f for f in system.getForces() if isinstance(f, openmm.HarmonicAngleForce)][0]
    idx = np.array([f.getAngleParameters(k)[:3] for k in range(f.getNumAngles())], int)
    t0 = np.array([f.getAngleParameters(k)[3].value_in_unit(openmm.unit.radian) for k in range(f.getNumAngles())])
    a, b = pos[idx[:, 0]] - pos[idx[:, 1]], pos[idx[:, 2]] - pos[idx[:, 1]]
    c = np.sum(a * b, axis=1) / np.linalg.norm(a, axis=1) / np.linalg.norm(b, axis=1)
    dev = np.degrees(np.abs(np.arccos(np.clip(c, -1.0, 1.0)) - t0))
    w = int(np.argmax(dev))
    i, j, k = idx[w]
    return float(dev[w]), f"{_atom_name(atoms[j])} {atoms[i].name}-{atoms[j].name}-{atoms[k].name}"


def _exclusion_pairs(n, bonds):
    nbr = [set() for _ in range(n)]
    for i, j in bonds:
        nbr[i].add(j)
        nbr[j].add(i)
    excl = set()
    for i in range(n):
        for j in nbr[i]:
            excl.add((min(i, j), max(i, j)))
            for k in nbr[j]:
                if k != i:
                    excl.add((min(i, k), max(i, k)))
    return excl


def _chirality(topology, xyz):
    """Signed volumes at the sugar stereocentres: {(residue index, centre): sign}."""
    out = {}
    for res_index, centre, (i_centre, i_a, i_b, i_c) in _sugar_stereocentres(topology):
        o = xyz[i_centre]
        out[(res_index, centre)] = np.sign(np.linalg.det(np.array([xyz[i_a] - o, xyz[i_b] - o, xyz[i_c] - o])))
    return out


def _links(topology):
    """(strand, step, O3' index, P index) of the inter-residue backbone bonds."""
    out = []
    for b in topology.bonds():
        a1, a2 = b.atom1, b.atom2
        if a1.residue is a2.residue:
            continue
        if a1.name == "P":
            a1, a2 = a2, a1
        if a1.name == "O3'" and a2.name == "P":
            out.append((a1, a2))
    return out


def _pair_frames_of(topology, xyz, n, sequence, sequence2):
    """Base-pair frames refitted from the rebuilt atoms (nm, as the analysis computes them)."""
    from dnarod.structure.bpparams import pair_parameters
    from dnarod.structure.frames import kabsch

    std, ring = standard_bases()
    res = list(topology.residues())
    F, O = np.zeros((2, n, 3, 3)), np.zeros((2, n, 3))
    for k in range(n):
        for s, r, letter in ((0, res[k], sequence[k]), (1, res[2 * n - 1 - k], sequence2[k])):
            idx = {a.name: a.index for a in r.atoms()}
            names = ring[letter]
            R, o, _ = kabsch(np.array([std[letter][a] for a in names]), xyz[[idx[a] for a in names]])
            F[s, k], O[s, k] = R, o
    _, mid, morg = pair_parameters(F[0], O[0], F[1], O[1])
    return mid, morg


def _frame_points(F, O, arm=0.5):
    """Origins and points ``arm`` nm along d1 and d2 of each frame, shape (3 n, 3)."""
    return np.concatenate([O, O + arm * F[:, :, 0], O + arm * F[:, :, 1]])


def _homotopy(F, O, fractions):
    """Chains whose steps go from the B-DNA fibre step to the input's: ``[(F_t, O_t)]`` per fraction.

    Step i is ``(R_i, d_i)`` in the frame of pair i (``R_i = F_i^T F_{i+1}``, ``d_i = F_i^T (O_{i+1} - O_i)``);
    at fraction t the rotation is ``R_fib exp(t log(R_fib^T R_i))`` and the offset ``(1 - t) d_fib + t d_i``.
    Each chain is superposed on the input origins (least squares) so that successive stages move the
    atoms locally only (origins and frame axes fitted); at t = 1 it is the input itself. Why: the rigid placement nearly closes the
    backbone on the fibre (the nucleotide template is the fibre's), so the backbone can follow the
    frames continuously from there instead of being untangled from a far-off start.
    """
    from scipy.spatial.transform import Rotation

    from dnarod.structure.frames import kabsch

    n = len(F)
    c, s_ = np.cos(FIBRE_TWIST), np.sin(FIBRE_TWIST)
    R_fib = np.array([[c, -s_, 0.0], [s_, c, 0.0], [0.0, 0.0, 1.0]])
    d_fib = np.array([0.0, 0.0, FIBRE_RISE])
    out = []
    if n < 2:
        return [(F, O) for _ in fractions]
    R_st = np.einsum("kji,kjl->kil", F[:-1], F[1:])
    d_st = np.einsum("kji,kj->ki", F[:-1], O[1:] - O[:-1])
    log = Rotation.from_matrix(np.einsum("ji,kjl->kil", R_fib, R_st)).as_rotvec()
    for t in fractions:
        if t >= 1.0:
            out.append((F, O))
            continue
        R = R_fib @ Rotation.from_rotvec(t * log).as_matrix()
        d = (1.0 - t) * d_fib + t * d_st
        Ft, Ot = np.empty_like(F), np.empty_like(O)
        Ft[0], Ot[0] = F[0], O[0]
        for k in range(n - 1):
            Ft[k + 1] = Ft[k] @ R[k]
            Ot[k + 1] = Ot[k] + Ft[k] @ d[k]
        # superpose on points that carry the frames' orientation too (B-DNA origins are collinear)
        Q, o, _ = kabsch(_frame_points(Ft, Ot), _frame_points(F, O))
        out.append((np.einsum("ij,kjl->kil", Q, Ft), Ot @ Q.T + o))
    return out


def _rotation_angle(A, B):
    c = (np.einsum("...ij,...ij->...", A, B) - 1.0) / 2.0
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def _hydrogenated(atoms, xyz, platform):
    """OpenMM topology with hydrogens (Amber14 templates) of a placement: ``(topology, positions nm, tmap)``.

    ``tmap[k]`` is the index in the new topology of heavy atom k of ``atoms``.
    """
    import openmm
    import openmm.app as app

    top = _topology(atoms, xyz)
    modeller = app.Modeller(top, xyz * openmm.unit.nanometer)
    ff = _amber_forcefield()
    modeller.addHydrogens(ff, platform=openmm.Platform.getPlatformByName(platform or "CPU"))
    top = modeller.topology
    pos = np.array(modeller.getPositions().value_in_unit(openmm.unit.nanometer))
    index = {(a.residue.chain.id, int(a.residue.id), a.name): a.index for a in top.atoms()}
    tmap = np.array([index[(c, num, name)] for c, num, _, name, _ in atoms])
    return top, pos, tmap


def _covalent_system(system, topology, positions, restraint_k, bonds):
    """The covalent terms of ``system`` with firm base restraints, sugar chirality holds and a capped repulsion.

    Returns ``(covalent system, restraint force, restraint groups)`` (see :func:`_restrain`).
    """
    import openmm

    covalent = openmm.System()
    for i in range(system.getNumParticles()):
        covalent.addParticle(system.getParticleMass(i))
    for f in system.getForces():
        if isinstance(f, (openmm.HarmonicBondForce, openmm.HarmonicAngleForce, openmm.PeriodicTorsionForce)):
            covalent.addForce(openmm.XmlSerializer.deserialize(openmm.XmlSerializer.serialize(f)))
    cforce, cgroups = _restrain(covalent, topology, positions, restraint_k)
    _hold_chirality(covalent, topology, positions)
    _soft_repulsion(covalent, topology, bonds)
    return covalent, cforce, cgroups


def _close(F, O, seq1, seq2, p_in, restraint_k, bond_tolerance, max_iterations, platform):
    """Staged backbone closure of one duplex (the whole input, or one window of it).

    ``F`` (m, 3, 3), ``O`` (m, 3) nm, ``p_in`` (m, 6) pair parameters. Returns ``(topology, positions nm,
    Amber14 system (restraints in force group 31), placement on the input frames nm)``; no checks.
    """
    import openmm

    xyz, atoms = rebuild_coordinates(F, O, seq1, p_in, seq2)
    # placements along the path from the fibre (backbone nearly closed) to the input frames and pair parameters
    p_fib = fibre_pair_parameters()
    stages = [rebuild_coordinates(Ft, Ot, seq1, (1.0 - t) * p_fib + t * p_in, seq2)[0] if t < 1.0 else xyz
              for t, (Ft, Ot) in zip(HOMOTOPY, _homotopy(F, O, HOMOTOPY))]
    top, pos, tmap = _hydrogenated(atoms, stages[0], platform)
    targets = []
    for x in stages:
        full = pos.copy()
        full[tmap] = x
        targets.append(full)
    heavy_ref = pos.copy()
    # stage 1: covalent terms only (HarmonicBond/Angle, PeriodicTorsion) + restraints
    system, _ = amber_system(top, cutoff=MIN_CUTOFF)
    bonds, r0 = _bond_table(system, top)
    covalent, cforce, cgroups = _covalent_system(system, top, heavy_ref, restraint_k, bonds)
    pos, _ = _minimise(covalent, pos, 1.0, max_iterations, platform)
    # stage 2: the full force field + restraints; the base targets follow the path from the fibre
    # to the input frames (soft restraints), then firm up on the input; before each stage the
    # targets take the bases' relaxed internal geometry on the exact placed frames (_retarget)
    force, groups = _restrain(system, top, heavy_ref, RESTRAINT_SCHEDULE[0])
    _hold_chirality(system, top, heavy_ref)
    ctx = _context(system, pos, platform)
    plan = [(RESTRAINT_SCHEDULE[0], x) for x in targets[:-1]] + [(k, targets[-1]) for k in RESTRAINT_SCHEDULE]
    for k, target in plan:
        ctx.setParameter("kr", k)
        _retarget(force, ctx, groups, pos, target)
        pos, _ = _relax(ctx, 0.1, max_iterations)
    ctx.setParameter("kr", restraint_k)
    for _ in range(1 + EXTRA_ROUNDS):  # L-BFGS can stop early on large systems: restart while a bond is off
        _retarget(force, ctx, groups, pos, targets[-1])
        pos, _ = _relax(ctx, 0.01, max_iterations)
        d = np.abs(np.linalg.norm(pos[bonds[:, 0]] - pos[bonds[:, 1]], axis=1) - r0)
        if d.max() <= bond_tolerance:
            break
    del ctx
    if d.max() > 0.2 * bond_tolerance:
        # stage 3: polish with the covalent terms (bonds POLISH_BOND_SCALE times stiffer), the capped
        # repulsion and the firm base restraints only, so that the bonds reach Amber14's lengths and the
        # frames their tolerance. Why not the full force field here: its non-bonded terms turn base pairs
        # against the firm restraints (up to 2 deg on a 10-bp thermal snapshot), and restraints firm enough
        # to stop that strain the ring bonds.
        _scale_bonds(covalent, POLISH_BOND_SCALE)
        cctx = _context(covalent, pos, platform)
        _retarget(cforce, cctx, cgroups, pos, targets[-1])
        pos, _ = _relax(cctx, 0.01, max_iterations)
        del cctx
    return top, pos, system, targets[-1]


def rebuild_allatom(bp_frames, bp_origins, sequence, bp_params=None, sequence2=None, restraint_k=RESTRAINT_K,
                    bond_tolerance=BOND_TOLERANCE, max_iterations=0, platform=None, window=WINDOW_CORE,
                    flank=WINDOW_FLANK, polish_iterations=POLISH_ITERATIONS):
    """All-atom duplex with a closed, Amber14-valid backbone from base-pair frames.

    Parameters
    ----------
    bp_frames : ndarray, shape (n, 3, 3)
        Base-pair (node) frames, directors as columns.
    bp_origins : ndarray, shape (n, 3)
        nm.
    sequence : str
        Strand I, 5'->3' (A, C, G, T).
    bp_params : ndarray, shape (n, 6) or (6,), optional
        Pair parameters (shear, stretch, stagger nm; buckle, propeller, opening rad); default
        the B-DNA fibre's.
    sequence2 : str, optional
        Strand II bases pairing positions 1..n (default the complement).
    restraint_k : float
        Harmonic restraint on each base heavy atom, kJ/mol/nm^2.
    bond_tolerance : float
        Largest accepted deviation of a covalent bond from Amber14's equilibrium, nm.
    max_iterations : int
        Minimiser iteration cap per stage of each window's closure (0: until converged).
    platform : str, optional
        OpenMM platform name (default CPU).
    window : int
        Base pairs whose atoms each window's closure keeps (the window's core).
    flank : int
        Base pairs closed on each side of a core and then discarded. A duplex of at most
        ``window + 2 * flank`` pairs is closed in one piece.
    polish_iterations : int
        Minimiser iteration cap per round of the global polish after the windows.

    Returns
    -------
    AllAtomDuplex
        Topology and positions with hydrogens (write without them with ``hydrogens=False``).

    Raises
    ------
    StructureError
        Bad frames or sequence, a backbone that cannot be closed (naming the step, the
        link length after closure and before it), a bond off Amber14 by more than
        ``bond_tolerance``, a heavy-atom clash under 2.2 A, a flipped sugar, or a base pair moved by
        more than 0.05 A or 1 degree (naming the pair).
    """
    import resource

    import openmm

    F = np.asarray(bp_frames, float)
    O = np.asarray(bp_origins, float)
    if F.ndim != 3:
        raise StructureError(f"rebuild: bp_frames must have shape (n, 3, 3), got {F.shape}")
    xyz, atoms = rebuild_coordinates(F, O, sequence, bp_params, sequence2)
    _placed_clash(xyz, atoms, F, O, len(F))
    _placed_gap(xyz, atoms, O, len(F), bond_tolerance)
    seq1 = "".join(str(sequence).split()).upper()
    comp = {"A": "T", "T": "A", "G": "C", "C": "G"}
    seq2 = "".join(str(sequence2).split()).upper() if sequence2 else "".join(comp[c] for c in seq1)
    n = len(seq1)
    t0, c0 = time.perf_counter(), resource.getrusage(resource.RUSAGE_SELF).ru_utime
    p_fib = fibre_pair_parameters()
    p_in = np.broadcast_to(p_fib if bp_params is None else np.asarray(bp_params, float), (n, 6))
    core, flank = int(window), int(flank)
    if core < 1 or flank < 1:
        raise StructureError(f"rebuild: window ({window}) and flank ({flank}) must be at least 1 bp")
    windowed = n > core + 2 * flank
    if not windowed:
        top, pos, system, placed = _close(F, O, seq1, seq2, p_in, restraint_k, bond_tolerance, max_iterations,
                                          platform)
        chiral0 = _chirality(top, placed)
        bonds, r0 = _bond_table(system, top)
    else:
        # the whole duplex's topology (hydrogens) on the input placement; every atom is then taken from the
        # window whose core holds its base pair
        top, placed, tmap = _hydrogenated(atoms, xyz, platform)
        placed[tmap] = xyz
        chiral0 = _chirality(top, placed)
        pos = placed.copy()
        index = {(a.residue.chain.id, int(a.residue.id), a.name): a.index for a in top.atoms()}
        taken = np.zeros(len(pos), bool)
        for a in range(0, n, core):
            b = min(n, a + core)
            lo, hi = max(0, a - flank), min(n, b + flank)
            wtop, wpos, _, _ = _close(F[lo:hi], O[lo:hi], seq1[lo:hi], seq2[lo:hi], p_in[lo:hi], restraint_k,
                                      bond_tolerance, max_iterations, platform)
            m = hi - lo
            _log.debug("rebuild: window %d-%d (core %d-%d) closed, %.1f s", lo + 1, hi, a + 1, b,
                       time.perf_counter() - t0)
            for at in wtop.atoms():
                k = lo + _pair_of(at.residue, m)  # 1-based pair of the whole duplex
                if a < k <= b:
                    rid = k if at.residue.chain.id == "A" else 2 * n + 1 - k
                    i = index[(at.residue.chain.id, rid, at.name)]
                    pos[i], taken[i] = wpos[at.index], True
        if not taken.all():  # cannot happen with standard residues; guards the atom bookkeeping
            miss = list(top.atoms())[int(np.flatnonzero(~taken)[0])]
            raise StructureError(f"rebuild: no window placed atom {_atom_name(miss)}")
        system, _ = amber_system(top, cutoff=MIN_CUTOFF)
        bonds, r0 = _bond_table(system, top)
        # global polish, capped: where two windows meet, the link and its neighbours come from different
        # windows (each closed with the same frames, so they differ by little); the covalent terms with
        # stiffened bonds, the capped repulsion, the firm base restraints and the sugar chirality hold
        # bring them to Amber14's lengths without the non-bonded terms turning the pairs (see stage 3)
        covalent, cforce, cgroups = _covalent_system(system, top, placed, restraint_k, bonds)
        _scale_bonds(covalent, POLISH_BOND_SCALE)
        cctx = _context(covalent, pos, platform)
        for _ in range(1 + EXTRA_ROUNDS):
            _retarget(cforce, cctx, cgroups, pos, placed)
            pos, _ = _relax(cctx, 0.01, polish_iterations)
            d = np.abs(np.linalg.norm(pos[bonds[:, 0]] - pos[bonds[:, 1]], axis=1) - r0)
            if d.max() <= 0.2 * bond_tolerance:
                break
        del cctx
    ctx = _context(system, pos, platform)
    energy = ctx.getState(getEnergy=True, groups={g for g in range(31)}).getPotentialEnergy().value_in_unit(
        openmm.unit.kilojoule_per_mole)
    del ctx
    links = _links(top)
    if len(links) != 2 * (n - 1):
        raise StructureError(f"rebuild: expected {2 * (n - 1)} O3'-P links, the topology has {len(links)}")
    place = np.array([np.linalg.norm(placed[a.index] - placed[b.index]) for a, b in links])
    targets = [placed]
    seconds = time.perf_counter() - t0
    cpu = resource.getrusage(resource.RUSAGE_SELF).ru_utime - c0
    # checks
    lengths = np.linalg.norm(pos[bonds[:, 0]] - pos[bonds[:, 1]], axis=1)
    dev = np.abs(lengths - r0)
    atoms_list = list(top.atoms())
    bond_index = {(int(i), int(j)): k for k, (i, j) in enumerate(bonds)}
    o3p = []
    for (a, b) in links:
        k = bond_index.get((a.index, b.index), bond_index.get((b.index, a.index)))
        o3p.append((lengths[k], r0[k]))
    o3p = np.array(o3p)
    link_k = [bond_index.get((a.index, b.index), bond_index.get((b.index, a.index))) for a, b in links]
    def step_of(j):
        r1, r2 = links[j][0].residue, links[j][1].residue
        return int(r1.id) if r1.chain.id == "A" else 2 * n + 1 - int(r2.id)

    def gap_near(pairs):
        """The O3'-P link touching base pairs ``pairs`` (1-based) that the frames placed furthest off."""
        js = [j for j in range(len(links)) if {step_of(j), step_of(j) + 1} & set(pairs)]
        if not js:
            return ""
        j = max(js, key=lambda j: abs(place[j] - r0[link_k[j]]))
        if abs(place[j] - r0[link_k[j]]) < 0.05:
            return ""
        return (f" (the input frames placed the O3'-P link of step {step_of(j)}-{step_of(j) + 1}, strand "
                f"{'I' if links[j][0].residue.chain.id == 'A' else 'II'}, at {10 * place[j]:.2f} A; Amber14 "
                f"{10 * r0[link_k[j]]:.2f} A, off by {10 * abs(place[j] - r0[link_k[j]]):.2f} A)")

    # a backbone that did not close: name the link whose frames put it furthest from Amber14's length among
    # the links next to a bond left off (a gap also strains the neighbouring links, more so where two
    # windows meet, so the worst link after minimisation need not be the step the frames broke)
    off = dev > bond_tolerance
    bad_res = {atoms_list[int(i)].residue.index for i in bonds[off].ravel()}
    near = [j for j, (a, b) in enumerate(links) if a.residue.index in bad_res or b.residue.index in bad_res]
    if near:
        j = max(near, key=lambda j: (abs(place[j] - r0[link_k[j]]), dev[link_k[j]]))
        a, b = links[j]
        k = link_k[j]
        r1, r2 = a.residue, b.residue
        step = int(r1.id) if r1.chain.id == "A" else 2 * n + 1 - int(r2.id)
        local = [q for q in np.flatnonzero(off) if {atoms_list[bonds[q, 0]].residue.index,
                                                     atoms_list[bonds[q, 1]].residue.index} & {r1.index, r2.index}]
        w = max(local, key=lambda q: dev[q]) if local else k
        worst_there = "" if w == k else (
            f"; worst bond there {_atom_name(atoms_list[bonds[w, 0]])}-{atoms_list[bonds[w, 1]].name} "
            f"{10 * lengths[w]:.2f} A, off by {10 * dev[w]:.2f} A")
        raise StructureError(
            f"rebuild: cannot close the backbone at step {step}-{step + 1} (strand {'I' if r1.chain.id == 'A' else 'II'}, "
            f"{r1.chain.id}:{r1.id} O3' - {r2.chain.id}:{r2.id} P): {10 * lengths[k]:.2f} A after minimisation "
            f"(placed at {10 * place[j]:.2f} A; Amber14 {10 * r0[k]:.2f} A, off by {10 * dev[k]:.2f} A{worst_there}); "
            f"the two base-pair frames are too far apart or too distorted for a DNA backbone")
    worst = int(np.argmax(dev))
    if dev[worst] > bond_tolerance:
        a, b = atoms_list[bonds[worst, 0]], atoms_list[bonds[worst, 1]]
        raise StructureError(f"rebuild: bond {_atom_name(a)}-{b.name} is {10 * lengths[worst]:.3f} A after "
                             f"minimisation, Amber14 {10 * r0[worst]:.3f} A; the frames are too distorted")
    chiral1 = _chirality(top, pos)
    flipped = [key for key, s in chiral0.items() if chiral1.get(key) != s]
    if flipped:
        r, centre = flipped[0]
        res = list(top.residues())[r]
        raise StructureError(f"rebuild: the sugar of {res.chain.id}:{res.id} changed chirality at {centre} while "
                             f"closing the backbone; the frames are too distorted{gap_near([_pair_of(res, n)])}")
    heavy = np.array([a.element.symbol != "H" for a in atoms_list])
    excl = _exclusion_pairs(len(atoms_list), bonds)
    from scipy.spatial import cKDTree

    hidx = np.flatnonzero(heavy)
    tree = cKDTree(pos[hidx])
    close = [(d, hidx[i], hidx[j]) for i, j in tree.query_pairs(0.3)
             if (min(hidx[i], hidx[j]), max(hidx[i], hidx[j])) not in excl
             for d in [np.linalg.norm(pos[hidx[i]] - pos[hidx[j]])]]
    dmin, pair = np.inf, None
    if close:
        d, i, j = min(close)
        dmin, pair = d, f"{_atom_name(atoms_list[i])} - {_atom_name(atoms_list[j])}"
    if dmin < MIN_NONBONDED:
        placed_d = np.linalg.norm(targets[-1][i] - targets[-1][j])
        where = _where(_pair_of(atoms_list[i].residue, n), _pair_of(atoms_list[j].residue, n))
        raise StructureError(f"rebuild: atoms {pair} ({where}) are {10 * dmin:.3f} A apart after minimisation "
                             f"(under {10 * MIN_NONBONDED:.1f} A, short by {10 * (MIN_NONBONDED - dmin):.3f} A); the "
                             f"frames put two nucleotides into each other (placed {10 * placed_d:.2f} A apart; the "
                             f"frames must move them further apart)")
    mid, morg = _pair_frames_of(top, pos, n, seq1, seq2)
    shift, turn = np.linalg.norm(morg - O, axis=-1), _rotation_angle(mid, F)
    bad = np.flatnonzero((shift > FRAME_ORIGIN_TOL) | (turn > FRAME_ANGLE_TOL))
    if len(bad):
        k = int(bad[np.argmax(shift[bad] / FRAME_ORIGIN_TOL + turn[bad] / FRAME_ANGLE_TOL)])
        raise StructureError(f"rebuild: base pair {k + 1} moved by {10 * shift[k]:.3f} A and {turn[k]:.2f} deg while "
                             f"closing the backbone (accepted {10 * FRAME_ORIGIN_TOL:.2f} A, {FRAME_ANGLE_TOL:.0f} deg); "
                             f"the frames are too distorted for an Amber14 backbone{gap_near([k + 1])}")
    ang_dev, worst_angle = _angle_deviation(system, pos, atoms_list)
    report = RebuildReport(
        max_bond_deviation=float(dev.max()), worst_bond=f"{_atom_name(atoms_list[bonds[worst, 0]])}-"
                                                         f"{atoms_list[bonds[worst, 1]].name}",
        o3p_range=(float(o3p[:, 0].min()), float(o3p[:, 0].max())) if len(o3p) else (np.nan, np.nan),
        o3p_equilibrium=float(o3p[0, 1]) if len(o3p) else np.nan,
        min_nonbonded=float(dmin), min_nonbonded_pair=str(pair),
        frame_origin_error=float(np.linalg.norm(morg - O, axis=-1).max()),
        frame_angle_error=float(_rotation_angle(mid, F).max()),
        placement_o3p_range=(float(place.min()), float(place.max())) if len(place) else (np.nan, np.nan),
        energy=float(energy), seconds=seconds, cpu_seconds=cpu, max_angle_deviation=ang_dev,
        worst_angle=worst_angle)
    return AllAtomDuplex(top, pos, report)


def write_allatom(path, topology, positions, hydrogens=True, remarks=()):
    """Write an all-atom structure as PDB or PDBx/mmCIF (by suffix), atomically.

    Parameters
    ----------
    path : str or Path
        ``.pdb`` or ``.cif``/``.mmcif``.
    topology : openmm.app.Topology
    positions : ndarray, shape (n_atoms, 3)
        nm.
    hydrogens : bool
        Keep hydrogens (default) or write heavy atoms only.
    """
    from pathlib import Path

    import openmm.app as app
    import openmm.unit as u

    from dnarod.core.io import atomic_path

    path = Path(path)
    top, pos = topology, np.asarray(positions, float)
    if not hydrogens:
        m = app.Modeller(top, pos * u.nanometer)
        m.delete([a for a in top.atoms() if a.element.symbol == "H"])
        top, pos = m.topology, np.array(m.getPositions().value_in_unit(u.nanometer))
    cif = path.suffix.lower() in (".cif", ".mmcif")
    with atomic_path(path) as tmp:
        with open(tmp, "w") as fh:
            if cif:
                app.PDBxFile.writeFile(top, pos * u.nanometer, fh, keepIds=True)
            else:
                for line in remarks:
                    fh.write(f"REMARK   1 {line}\n")
                app.PDBFile.writeFile(top, pos * u.nanometer, fh, keepIds=True)
