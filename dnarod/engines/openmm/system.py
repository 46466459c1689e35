"""Build an OpenMM System and Topology from a :class:`~dnarod.core.model.RodModel`.

Particles: node k owns particles ``3k, 3k+1, 3k+2`` (mass ``m_k/3`` each, rigid equilateral
triangle of circumradius ``l_k = sqrt(J3_k/m_k)`` held by three constraints; see
:mod:`dnarod.engines.openmm.particles`). Clamped nodes get zero-mass particles and no constraints.

Forces (force groups in :data:`dnarod.engines.openmm.forces.GROUPS`):

* elastic step energy -- ``"plugin"`` (the compiled SMKForce, :mod:`dnarod.engines.openmm.plugin`), ``"fast"``
  (numba analytic loads through ``PythonForce``) or ``"portable"`` (CustomCompoundBondForce); ``"auto"`` picks the
  plugin, else the fast path, on the CPU and Reference platforms; on GPU platforms (CUDA, OpenCL, HIP), where a
  Python callback would copy positions off the device every step, it picks the plugin where its device kernel is
  loaded for that platform (:func:`dnarod.engines.openmm.plugin.device_kernel`: SMKForce and the rigid-body
  integrator's steps on the device), else the portable expression;
* non-local terms (:mod:`dnarod.engines.openmm.nonbonded`), on by default: with the fast elastic path
  they are evaluated inside the elastic callback (one ``PythonForce``, force group
  ``"elastic"``; the per-term split is read from the callbacks), with the portable path by
  their own ``PythonForce`` in group ``"nonbonded"``;
* external loads (:mod:`dnarod.engines.openmm.loads`).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import openmm
from openmm import app

from dnarod.core.errors import GeometryError, ParameterError
from dnarod.core.forcefield import COMPLEMENT
from dnarod.engines.openmm import plugin
from dnarod.engines.openmm.forces import (ElasticCallback, add_closure_image, elastic_compound_forces,
                                          elastic_python_force)
from dnarod.engines.openmm.loads import build_load_forces
from dnarod.engines.openmm.nonbonded import nonbonded_force
from dnarod.physics.nonbonded import NonbondedSettings
from dnarod.engines.openmm.particles import SQRT3, triangle_radius
from dnarod.engines.openmm.platforms import CALLBACK_PLATFORMS
from dnarod.core.model import RodModel


def base_pair_names(model: RodModel) -> list[str]:
    """Residue name of every node: its base pair (``"AT"``, ``"GC"``, ...), or ``"BP"`` without sequence."""
    if not model.sequence:
        return ["BP"] * model.n_nodes
    return [f"{b}{COMPLEMENT.get(b, 'N')}" for b in model.sequence.upper()]


def check_overlaps(model: RodModel, min_distance: float | None = None) -> None:
    """Raise GeometryError if two nodes overlap (centres closer than ``min_distance``, default ds/4).

    Uses a grid on the centres, so it costs O(n).
    """
    from scipy.spatial import cKDTree

    d = model.ds / 4 if min_distance is None else min_distance
    pairs = cKDTree(model.positions).query_pairs(d, output_type="ndarray")
    if len(pairs):
        i, j = map(int, pairs[0])
        dist = np.linalg.norm(model.positions[i] - model.positions[j])
        raise GeometryError(f"nodes {i} and {j} overlap: centres {dist:.4g} nm apart (less than {d:.4g} nm); "
                            f"fix the model's positions")


@dataclass
class RodSystem:
    """An OpenMM system for a rod model.

    Attributes
    ----------
    system : openmm.System
    radius : ndarray, shape (n_nodes,)
        Triangle circumradius, nm.
    elastic : str
        ``"plugin"``, ``"fast"`` or ``"portable"``.
    clamped : list of int
        Clamped nodes.
    load_info : dict
        From :func:`dnarod.engines.openmm.loads.build_load_forces`.
    nonbonded : dict or None
        Resolved non-local numbers (Debye length, charge, cutoff, ...), ``None`` if off.
    device : bool
        ``elastic == "plugin"`` on a GPU platform where the plugin's device kernels are loaded: the SMKForce is
        evaluated there and the rigid-body integrator steps there (no host copies per step).
    loads : tuple
        The load dataclasses the system was built with.
    image : int or None
        Portable path of a circular chain: index of the first of the three massless image particles of node 0
        (``3 n``; :func:`dnarod.engines.openmm.forces.add_closure_image`), else ``None`` (also for a plain ring, whose
        closing step ends on node 0 itself). The nodes' particles are always ``0 .. 3n-1``.
    """

    system: Any  # openmm.System
    radius: np.ndarray
    elastic: str
    clamped: list[int] = field(default_factory=list)
    load_info: dict[str, Any] = field(default_factory=dict)
    nonbonded: dict[str, Any] | None = None
    nonbonded_callback: Any = None
    elastic_callback: Any = None
    residue_names: list[str] = field(default_factory=list)
    device: bool = False
    image: int | None = None
    loads: tuple[Any, ...] = ()

    @property
    def topology(self) -> Any:
        """The OpenMM Topology (built on first use: one chain, one residue per node named by its
        base pair, atoms P0, P1, P2 bonded in a triangle, P0 bonded along the chain). With closure image
        particles (``image`` set) a last residue ``IMG`` holds their three atoms I0, I1, I2, so the topology has
        one atom per particle of ``system``, as OpenMM's reporters require (virtual sites are atoms there too)."""
        if getattr(self, "_topology", None) is None:
            topology = app.Topology()
            chain = topology.addChain("A")
            prev = None
            for k, name in enumerate(self.residue_names):
                res = topology.addResidue(name, chain, id=str(k + 1))
                atoms = [topology.addAtom(f"P{i}", None, res) for i in range(3)]
                topology.addBond(atoms[0], atoms[1])
                topology.addBond(atoms[1], atoms[2])
                topology.addBond(atoms[0], atoms[2])
                if prev is not None:
                    topology.addBond(prev, atoms[0])
                prev = atoms[0]
            if self.image:
                res = topology.addResidue("IMG", chain, id=str(len(self.residue_names) + 1))
                for i in range(3):
                    topology.addAtom(f"I{i}", None, res)
            self._topology = topology
        return self._topology

    @property
    def degrees_of_freedom(self) -> int:
        """6 per free node."""
        return 6 * (self.radius.size - len(self.clamped))


def choose_elastic(elastic: str, platform: str) -> str:
    """The elastic path for a platform: ``"auto"`` takes the compiled plugin on CPU/Reference when it is usable
    (saying once which path and why, :mod:`dnarod.engines.openmm.plugin`), else the Python-callback ``"fast"`` path
    there; on OpenCL/CUDA the plugin when its device kernel is loaded for that platform (saying once which
    path and why), else the ``"portable"`` expression, as on other GPU platforms."""
    if elastic == "auto":
        if platform in plugin.PLUGIN_PLATFORMS:
            plugin.announce()
            return "plugin" if plugin.status().available else "fast"
        if platform in plugin.DEVICE_PLATFORMS:
            plugin.announce_device(platform)
            if plugin.device_kernel(platform)[0]:
                return "plugin"
        return "fast" if platform in CALLBACK_PLATFORMS else "portable"
    if elastic not in ("fast", "portable", "plugin"):
        raise ParameterError(f"elastic must be 'auto', 'plugin', 'fast' or 'portable', got {elastic!r}")
    return elastic


def build_system(model: RodModel, platform: str = "CPU", elastic: str = "auto", nonbonded: Any = True,
                 loads: Sequence[Any] = (), temperature: float = 300.0) -> RodSystem:
    """Build the OpenMM System and Topology of a model.

    Parameters
    ----------
    model : RodModel
    platform : str
        Platform name (used to choose the elastic path for ``elastic="auto"``).
    elastic : {"auto", "plugin", "fast", "portable"}
        See :func:`choose_elastic`.
    nonbonded : bool or NonbondedSettings
        ``True`` for the defaults, ``False``/``None`` for none.
    loads : sequence
        External loads (:mod:`dnarod.engines.openmm.loads`).
    temperature : float
        K (energy scale of the WCA term and the Bjerrum length).

    Returns
    -------
    RodSystem
    """
    radius = triangle_radius(model.mass, model.inertia)
    check_overlaps(model)
    elastic = choose_elastic(elastic, platform)
    n = model.n_nodes
    system = openmm.System()
    info = build_load_forces(list(loads), model, radius, system)
    clamped = set(info["clamped"])
    for k in range(n):
        for _ in range(3):
            system.addParticle(0.0 if k in clamped else model.mass[k] / 3.0)
    for k in range(n):
        if k in clamped:
            continue
        side = SQRT3 * radius[k]
        for i, j in ((0, 1), (1, 2), (0, 2)):
            system.addConstraint(3 * k + i, 3 * k + j, side)
    nb_numbers = None
    nb_cb = None
    nb_force = None
    if nonbonded:
        settings = nonbonded if isinstance(nonbonded, NonbondedSettings) else NonbondedSettings()
        nb_force, nb_numbers = nonbonded_force(model, settings, temperature)
        if nb_force is not None:
            _check_nonbonded_overlaps(model, nb_numbers)
            if elastic == "plugin":  # the same terms compiled (a Verlet list in C++)
                nb_force = plugin.node_pair_force(model, nb_numbers)
                nb_cb = plugin.PairEnergies(nb_force)
            else:
                nb_cb = nb_force.dnarod_callback
        else:
            nb_numbers = None
    elastic_cb: Any = None
    image = None
    device = elastic == "plugin" and platform not in plugin.PLUGIN_PLATFORMS and plugin.device_kernel(platform)[0]
    if elastic == "plugin":
        smk = plugin.smk_force(model, radius)
        system.addForce(smk)
        # a device kernel does not record the last energy on the host: energies are read per force group
        elastic_cb = None if device else plugin.ElasticEnergy(smk)
    elif elastic == "fast":
        # The non-local terms ride in the elastic callback (one State hand-over per step; group "elastic").
        elastic_cb = ElasticCallback(model, radius, nonbonded=nb_cb)
        system.addForce(elastic_python_force(model, radius, callback=elastic_cb))
    else:
        first = add_closure_image(system, model) if model.closure is not None else None
        for f in elastic_compound_forces(model, radius, image=first):
            system.addForce(f)
        image = first or None  # 0: a plain ring's node 0 is its own image (no particles added)
    if nb_force is not None and elastic != "fast":  # fast: evaluated inside the elastic callback
        if image is not None:  # the callback sees the nodes' particles only
            nb_force.setParticles(list(range(3 * n)))
        system.addForce(nb_force)
    return RodSystem(system, radius, elastic, sorted(clamped), info, nb_numbers, nb_cb, elastic_cb,
                     residue_names=base_pair_names(model), device=bool(device), image=image, loads=tuple(loads))


def _check_nonbonded_overlaps(model: RodModel, numbers: dict[str, Any]) -> None:
    """Non-excluded node pairs far inside the WCA core (energy above ~1000 kT) are an input error."""
    if numbers["eps"] <= 0:
        return
    from scipy.spatial import cKDTree

    d = 0.5 * numbers["sigma"]
    pairs = cKDTree(model.positions).query_pairs(d, output_type="ndarray")
    if len(pairs) == 0:
        return
    n = model.n_nodes
    sep = np.abs(pairs[:, 1] - pairs[:, 0])
    if model.closure is not None:
        sep = np.minimum(sep, n - sep)
    bad = pairs[sep > numbers["n_exclude"]]
    if len(bad):
        i, j = map(int, bad[0])
        dist = np.linalg.norm(model.positions[i] - model.positions[j])
        raise GeometryError(f"nodes {i} and {j} overlap: centres {dist:.3g} nm apart, less than half the excluded-"
                            f"volume diameter {numbers['sigma']} nm; fix the model or switch excluded volume off")
