"""The planar walls of a magnetic-tweezers member: the surface under the anchored end, the bead above the pulled one.

Node ``k`` owns particles ``3k, 3k+1, 3k+2`` (:mod:`dnarod.engines.openmm.particles`); node 0 is anchored at the
surface, node ``n-1`` is pulled along +z. With ``z`` the particles' z coordinates (nm) and ``k`` the stiffness
(kJ/mol/nm^2), the energy (kJ/mol) is

* surface (a fixed plane at ``z_0``, node 0's z at the start): ``E_s = k/2 sum_p min(0, z_p - z_0)^2`` over the
  three particles of every node ``skip .. n-1``;
* bead (a plane through the pulled node: the large-bead limit): ``E_b = k/2 sum_i max(0, z_{3i} - z_c)^2`` over the
  first particle of every node ``0 .. n-1-skip``, with ``z_c`` the mean z of node ``n-1``'s three particles
  (the reaction, ``+k (z_{3i} - z_c)`` along z, is spread equally over them).

Three implementations of the same energy and forces (tested equal to 1e-10 relative in double precision):

* :func:`wall_forces_compiled` -- ``dnarod.WallForce`` of the compiled plugin (:mod:`dnarod.engines.openmm.plugin`): one
  C++ pass over the particles, evaluated on the host (OpenMM's ``CustomCPPForceImpl``);
* :func:`wall_forces_numba` -- the same pass as a numba kernel in an ``openmm.PythonForce`` (host platforms, where
  the plugin is not built): cheaper than the Custom forces by the kernel, dearer than the compiled force by the
  callback's hand-over of the positions (written here because no library provides planar walls);
* :func:`wall_forces_reference` -- the slow reference and the fallback: an OpenMM ``CustomExternalForce`` (surface)
  and ``CustomCentroidBondForce`` (bead), Lepton expressions that run on every platform, the GPU ones included.
  On the host platforms they were the expensive part of a member's step: OpenMM's CPU platform has no kernel of its
  own for either force and runs the Reference kernels, single-threaded, which for every particle (every bond) load
  the variables of a compiled Lepton expression and evaluate the energy and its derivatives. The surface acts on
  all three particles of each node (2 991 particles at 1 kbp), so their cost grows with the particle count.

:func:`wall_forces` picks, on the host platforms (CPU, Reference), the compiled form when the plugin is usable and
the numba form when it is not; on GPU platforms the Custom forces (a host force would copy positions off the device
every step). Every form puts
its forces in force group ``GROUPS["external"]``, with the loads (pulling force, clamps), so the walls' energy is
reported in the "external" term.
"""
from __future__ import annotations

import numba
import numpy as np
import openmm

from dnarod.engines.openmm.forces import GROUPS, python_force
from dnarod.engines.openmm import plugin
from dnarod.core.errors import ParameterError

#: Platforms on which :func:`wall_forces` takes a host form (compiled, else numba): no copies off a device.
COMPILED_WALL_PLATFORMS = ("CPU", "Reference")


def _check(n_nodes, skip):
    n, skip = int(n_nodes), int(skip)
    if not 0 <= skip < n:
        raise ParameterError(f"wall skip must be in 0 .. n_nodes-1 = {n - 1}, got {skip}")
    return n, skip


def wall_forces_reference(n_nodes, z_surface, k, skip):
    """The walls as OpenMM Custom forces (the reference form; every platform).

    Parameters
    ----------
    n_nodes : int
        Nodes of the chain (particles ``0 .. 3 n_nodes - 1``).
    z_surface : float
        z of the surface plane, nm.
    k : float
        Stiffness of both walls, kJ/mol/nm^2.
    skip : int
        Nodes next to each end left alone (the surface skips nodes ``0 .. skip-1``, the bead ``n-skip .. n-1``).

    Returns
    -------
    list of openmm.Force
        ``[CustomExternalForce (surface), CustomCentroidBondForce (bead)]``, both in group ``GROUPS["external"]``.
    """
    n, skip = _check(n_nodes, skip)
    wall = openmm.CustomExternalForce("0.5*dnarod_wall_k*min(0, z - dnarod_surface_z)^2")
    wall.addGlobalParameter("dnarod_wall_k", float(k))
    wall.addGlobalParameter("dnarod_surface_z", float(z_surface))
    for i in range(3 * skip, 3 * n):
        wall.addParticle(i, [])
    wall.setForceGroup(GROUPS["external"])
    wall.setName("dnarod tweezers surface")
    bead = openmm.CustomCentroidBondForce(2, "0.5*dnarod_bead_k*max(0, z1 - z2)^2")
    bead.addGlobalParameter("dnarod_bead_k", float(k))
    last = bead.addGroup([3 * (n - 1), 3 * (n - 1) + 1, 3 * (n - 1) + 2], [1.0, 1.0, 1.0])
    for i in range(n - skip):
        g = bead.addGroup([3 * i], [1.0])
        bead.addBond([g, last], [])
    bead.setForceGroup(GROUPS["external"])
    bead.setName("dnarod tweezers bead plane")
    return [wall, bead]


def compiled_walls_available():
    """Whether the compiled plugin is usable here and has ``WallForce`` (a plugin built before it has not)."""
    mod = plugin.module()
    return mod is not None and hasattr(mod, "WallForce")


def wall_forces_compiled(n_nodes, z_surface, k, skip):
    """The walls as one compiled ``dnarod.WallForce`` (host code on every platform).

    Parameters and particle sets as :func:`wall_forces_reference`.

    Returns
    -------
    list of openmm.Force
        ``[WallForce]`` in group ``GROUPS["external"]``; its ``getLastSurface()``, ``getLastBead()`` give the two
        energies (kJ/mol) of the last evaluation.

    Raises
    ------
    ParameterError
        If the compiled plugin (with ``WallForce``) is not usable here.
    """
    n, skip = _check(n_nodes, skip)
    if not compiled_walls_available():
        reason = plugin.status().reason or "the installed plugin was built without WallForce: reinstall dnarod"
        raise ParameterError(f"the compiled tweezers walls need the compiled OpenMM plugin, which is not usable "
                             f"here ({reason})")
    f = plugin.module().WallForce()
    f.setParameters(float(z_surface), float(k), float(k))
    for i in range(3 * skip, 3 * n):
        f.addSurfaceParticle(i)
    f.setBeadNode(3 * (n - 1), 3 * (n - 1) + 1, 3 * (n - 1) + 2)
    for i in range(n - skip):
        f.addBeadParticle(3 * i)
    f.setForceGroup(GROUPS["external"])
    f.setName("dnarod tweezers walls (surface + bead plane, plugin)")
    return [f]


@numba.njit(cache=True)
def _wall_kernel(p, z0, k, skip, n, out):
    """Energy of the walls for particle positions ``p`` (>= 3n, 3) nm; adds the z forces to ``out`` (3n, 3)."""
    e = 0.0
    for i in range(3 * skip, 3 * n):
        d = p[i, 2] - z0
        if d < 0.0:
            e += 0.5 * k * d * d
            out[i, 2] -= k * d
    zc = (p[3 * n - 3, 2] + p[3 * n - 2, 2] + p[3 * n - 1, 2]) / 3.0
    fc = 0.0
    for i in range(n - skip):
        d = p[3 * i, 2] - zc
        if d > 0.0:
            e += 0.5 * k * d * d
            out[3 * i, 2] -= k * d
            fc += k * d
    for j in range(3):
        out[3 * n - 3 + j, 2] += fc / 3.0
    return e


class WallCallback:
    """Picklable ``openmm.PythonForce`` computation of the walls (:func:`wall_forces_numba`).

    Parameters
    ----------
    n_nodes : int
    z_surface : float
        nm.
    k : float
        kJ/mol/nm^2.
    skip : int
    n_particles : int
        Particles of the System (forces are returned for all of them; those past the nodes' get none).
    """

    def __init__(self, n_nodes, z_surface, k, skip, n_particles):
        self.n, self.z0, self.k, self.skip, self.n_particles = (int(n_nodes), float(z_surface), float(k), int(skip),
                                                                int(n_particles))
        self._out = np.zeros((self.n_particles, 3))

    def __call__(self, state):
        p = state.getPositions(asNumpy=True)._value
        out = self._out
        out[:] = 0.0
        e = _wall_kernel(p, self.z0, self.k, self.skip, self.n, out)
        return e, out

    def __getstate__(self):
        return dict(n=self.n, z0=self.z0, k=self.k, skip=self.skip, n_particles=self.n_particles)

    def __setstate__(self, d):
        self.__dict__.update(d)
        self._out = np.zeros((self.n_particles, 3))


def wall_forces_numba(n_nodes, z_surface, k, skip, n_particles=None):
    """The walls as a numba kernel in an ``openmm.PythonForce`` (CPU and Reference platforms).

    Parameters
    ----------
    n_nodes, z_surface, k, skip
        As :func:`wall_forces_reference` (nm, kJ/mol/nm^2).
    n_particles : int or None
        Particles of the System the force goes into (default ``3 n_nodes``; more when the System has particles
        after the nodes', e.g. the portable path's closure image).

    Returns
    -------
    list of openmm.Force
        ``[PythonForce]`` in group ``GROUPS["external"]``.
    """
    n, skip = _check(n_nodes, skip)
    f = python_force(WallCallback(n, z_surface, k, skip, 3 * n if n_particles is None else n_particles))
    f.setForceGroup(GROUPS["external"])
    f.setName("dnarod tweezers walls (surface + bead plane, numba)")
    return [f]


def wall_forces(n_nodes, z_surface, k, skip, platform="CPU", form="auto"):
    """The tweezers walls in the form that is fastest on ``platform``.

    Parameters
    ----------
    n_nodes, z_surface, k, skip
        As :func:`wall_forces_reference` (nm, kJ/mol/nm^2).
    platform : str
        The OpenMM platform name the forces will run on.
    form : {"auto", "compiled", "numba", "reference"}
        ``"auto"``: on :data:`COMPILED_WALL_PLATFORMS` the compiled form when the plugin is usable, else the numba
        form; the reference on every other platform.

    Returns
    -------
    list of openmm.Force
    """
    if form == "auto":
        if platform in COMPILED_WALL_PLATFORMS:
            form = "compiled" if compiled_walls_available() else "numba"
        else:
            form = "reference"
    if form == "compiled":
        return wall_forces_compiled(n_nodes, z_surface, k, skip)
    if form == "numba":
        return wall_forces_numba(n_nodes, z_surface, k, skip)
    if form == "reference":
        return wall_forces_reference(n_nodes, z_surface, k, skip)

    raise ParameterError(f"wall form must be 'auto', 'compiled', 'numba' or 'reference', got {form!r}")


def wall_energy(z, n_nodes, z_surface, k, skip):
    """Energy and z forces of the walls for particle z coordinates (numpy; for checks).

    Parameters
    ----------
    z : ndarray, shape (3 n_nodes,)
        Particle z coordinates, nm.
    n_nodes, z_surface, k, skip
        As :func:`wall_forces_reference`.

    Returns
    -------
    (float, float, ndarray of shape (3 n_nodes,))
        Surface energy, bead energy (kJ/mol) and the z component of the force on every particle (kJ/mol/nm).
    """
    n, skip = _check(n_nodes, skip)
    z = np.asarray(z, float)
    fz = np.zeros(3 * n)
    d = np.minimum(0.0, z[3 * skip:3 * n] - float(z_surface))
    e_s = 0.5 * k * float(np.sum(d * d))
    fz[3 * skip:3 * n] -= k * d
    zc = z[3 * (n - 1):3 * n].sum() / 3.0
    d = np.maximum(0.0, z[0:3 * (n - skip):3] - zc)
    e_b = 0.5 * k * float(np.sum(d * d))
    fz[0:3 * (n - skip):3] -= k * d
    fz[3 * (n - 1):3 * n] += k * float(d.sum()) / 3.0
    return e_s, e_b, fz
