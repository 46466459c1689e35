"""The compiled OpenMM plugin: loading, the ABI check against the installed OpenMM, and the fallback.

``pip install`` compiles ``dnarod/_plugin/cpp`` (C++ force and integrator plus a SWIG wrapper) against the
openmm wheel of the build environment, if it can; ``dnarod/_plugin/_build_info.py`` records whether it did,
why not, and the OpenMM version it was built against. At first use (never at import of dnarod) this module
checks that record against the OpenMM installed now and loads the extension; if anything is missing or
does not match, dnarod uses its Python-callback path (:func:`dnarod.engines.openmm.forces.elastic_python_force`)
and says so once, naming the reason (and both OpenMM versions for a mismatch). ``DNAROD_PLUGIN=0`` in the
environment switches the plugin off, ``DNAROD_DEVICE_KERNELS=0`` only its device kernels (the plugin then runs
as host code on GPU platforms too).

What the plugin provides (:func:`smk_force`): ``dnarod.SMKForce``, the SMK step energy of
:mod:`dnarod.core.energy` (exact Cayley strains, full 6x6 stiffness and intrinsic strains per step, screw
closure of circular chains) on the three-particle nodes of :mod:`dnarod.engines.openmm.particles`, evaluated in C++
on the host on every platform (OpenMM's CustomCPPForceImpl), and on the device on GPU platforms (OpenCL,
CUDA) whose Common-compute kernel library was built (:func:`device_kernel`; the build records which ones in
``_build_info.DEVICE_KERNELS`` and why the others were not built); that library also runs the rigid-body
integrator's steps on the device. Host code only: ``dnarod.NodePairForce`` (:func:`node_pair_force`, the
non-local terms) and ``dnarod.WallForce`` (:func:`dnarod.engines.openmm.walls.wall_forces_compiled`, the tweezers
walls).
"""
from __future__ import annotations

import os
import sys
from dataclasses import dataclass

import numpy as np

from dnarod.core.errors import ParameterError
from dnarod._plugin import _build_info

#: Host platforms on which ``elastic="auto"`` takes the plugin (SMKForce as host code, rigid-body integrator).
PLUGIN_PLATFORMS = ("CPU", "Reference")
#: GPU platforms on which ``elastic="auto"`` takes the plugin when its device kernels are loaded there
#: (:func:`device_kernel`): SMKForce and the rigid-body integrator's steps on the device (no host copies per step).
DEVICE_PLATFORMS = ("OpenCL", "CUDA")


@dataclass(frozen=True)
class PluginStatus:
    """Whether the compiled plugin is usable here.

    Attributes
    ----------
    available : bool
    reason : str
        Why not (empty if available).
    built_against : str
        OpenMM version the plugin was compiled against ("" if it was not built).
    installed : str
        OpenMM version installed now.
    """

    available: bool
    reason: str
    built_against: str
    installed: str

    def message(self):
        """One line: which elastic-force path dnarod uses and why."""
        if self.available:
            return f"dnarod: using the compiled OpenMM plugin (built against OpenMM {self.built_against})"
        return f"dnarod: compiled OpenMM plugin not used ({self.reason}); using the Python-callback path"


_STATUS = None
_MODULE = None
_ANNOUNCED = False


def _check_switch(name):
    """An on/off environment switch must be unset, empty, 0 or 1 (a typo must not silently mean "on")."""
    value = os.environ.get(name, "").strip()
    if value not in ("", "0", "1"):
        raise ParameterError(f"environment variable {name}={value!r}: use 0 (off) or 1 (on), or unset it")


def _installed_openmm():
    import openmm.version

    return openmm.version.full_version


def _load():
    """Load the extension; returns ``(PluginStatus, module or None)``. Never raises, except ParameterError for a
    misspelt DNAROD_PLUGIN switch."""
    installed = _installed_openmm()
    _check_switch("DNAROD_PLUGIN")
    if os.environ.get("DNAROD_PLUGIN", "").strip() == "0":
        return PluginStatus(False, "switched off by DNAROD_PLUGIN=0", "", installed), None
    try:
        from dnarod._plugin import _build_info  # the compiled extension, optional
    except ImportError:
        return PluginStatus(False, "dnarod was installed without its build step (no dnarod/_plugin/_build_info.py); "
                                   "reinstall with pip install -e .", "", installed), None
    built = getattr(_build_info, "OPENMM_VERSION", "")
    if getattr(_build_info, "STATUS", "") != "built":
        return PluginStatus(False, f"it was not built at install time: {_build_info.REASON}", built, installed), None
    if built != installed:
        return PluginStatus(False, f"it was built against OpenMM {built} but OpenMM {installed} is installed; "
                                   f"reinstall dnarod (pip install -e .) to rebuild it", built, installed), None
    try:
        from dnarod._plugin import dnarodplugin as mod  # the compiled extension, optional
    except Exception as exc:  # noqa: BLE001 - any load failure (ImportError, OSError, undefined symbol) falls back
        return PluginStatus(False, f"it failed to load ({type(exc).__name__}: {exc}; built against OpenMM {built}, "
                                   f"installed OpenMM {installed})", built, installed), None
    if mod.builtAgainstOpenMM() != installed:
        return PluginStatus(False, f"the loaded library was built against OpenMM {mod.builtAgainstOpenMM()} but "
                                   f"OpenMM {installed} is installed", built, installed), None
    return PluginStatus(True, "", built, installed), mod


def status():
    """The :class:`PluginStatus` of this process (computed once).

    Loading the extension also loads its device-kernel libraries into OpenMM (:func:`device_kernel`), so every
    Context created afterwards on such a platform evaluates SMKForce on the device, whichever way the force
    was made."""
    global _STATUS, _MODULE
    if _STATUS is None:
        _STATUS, _MODULE = _load()
        if _STATUS.available:
            for name in DEVICE_PLATFORMS:
                device_kernel(name)
    return _STATUS


def module():
    """The SWIG module ``dnarodplugin``, or ``None`` if the plugin is not usable here."""
    status()
    return _MODULE


def announce(stream=None):
    """Print :meth:`PluginStatus.message` once per process (to stderr)."""
    global _ANNOUNCED
    if not _ANNOUNCED:
        _ANNOUNCED = True
        print(status().message(), file=stream or sys.stderr)


_DEVICE = {}
_DEVICE_ANNOUNCED = set()


def device_kernel(platform):
    """Whether SMKForce runs on the device of a GPU platform here, and why not.

    Loads the platform's kernel library built with the plugin (``dnarod/_plugin/libdnarod_opencl.so``, ...)
    into OpenMM at the first call (``openmm.Platform.loadPluginLibrary``); never raises.

    Parameters
    ----------
    platform : str
        OpenMM platform name ("OpenCL", "CUDA").

    Returns
    -------
    (bool, str)
        True and "" if a Context on ``platform`` evaluates SMKForce with the device kernel; else False and the
        reason (plugin not usable, kernel library not built and why, platform missing, library failed to load).
    """
    if platform in _DEVICE:
        return _DEVICE[platform]
    _DEVICE[platform] = out = _load_device_kernel(platform)
    return out


def _load_device_kernel(platform):
    if platform not in DEVICE_PLATFORMS:
        return False, f"the plugin has no device kernel for the {platform} platform"
    _check_switch("DNAROD_DEVICE_KERNELS")
    if os.environ.get("DNAROD_DEVICE_KERNELS", "").strip() == "0":
        return False, "device kernels switched off by DNAROD_DEVICE_KERNELS=0"
    st = status()
    if not st.available:
        return False, f"the compiled plugin is not usable ({st.reason})"

    built = getattr(_build_info, "DEVICE_KERNELS", {})
    if platform not in built:
        why = getattr(_build_info, "DEVICE_KERNELS_NOT_BUILT", {}).get(platform, "this build predates device kernels; "
                                                                          "reinstall dnarod (pip install -e .)")
        return False, f"its {platform} kernel library was not built: {why}"
    import openmm

    names = [openmm.Platform.getPlatform(i).getName() for i in range(openmm.Platform.getNumPlatforms())]
    if platform not in names:
        return False, f"OpenMM has no {platform} platform here"
    path = os.path.join(os.path.dirname(_MODULE.__file__), built[platform])
    if not os.path.exists(path):
        return False, f"its {platform} kernel library {path} is missing; reinstall dnarod (pip install -e .)"
    try:
        openmm.Platform.loadPluginLibrary(path)
    except Exception as exc:  # noqa: BLE001 - any load failure falls back to the host code
        return False, f"its {platform} kernel library failed to load ({type(exc).__name__}: {exc})"
    if not openmm.Platform.getPlatformByName(platform).supportsKernels(["DnarodCalcSMKForce",
                                                                        "DnarodIntegrateRigidBodyStep"]):
        return False, f"its {platform} kernel library loaded but did not register its kernels"
    return True, ""


def announce_device(platform, stream=None):
    """Print once per process and platform whether SMKForce runs on the device of ``platform`` (to stderr)."""
    if platform in _DEVICE_ANNOUNCED:
        return
    _DEVICE_ANNOUNCED.add(platform)
    ok, why = device_kernel(platform)
    if ok:
        msg = (f"dnarod: using the compiled OpenMM plugin's {platform} kernels (SMK force and rigid-body steps on "
               f"the device, built against OpenMM {status().built_against})")
    else:
        msg = f"dnarod: compiled OpenMM plugin not used on {platform} ({why}); using the portable path"
    print(msg, file=stream or sys.stderr)


def _reset_for_tests():
    """Forget the cached status (tests change the environment)."""
    global _STATUS, _MODULE, _ANNOUNCED
    _STATUS, _MODULE, _ANNOUNCED = None, None, False
    _DEVICE.clear()
    _DEVICE_ANNOUNCED.clear()


def _module_and_particles(model, particles, what, advice=""):
    """The loaded plugin module and the (n_nodes, 3) particle indices of the nodes (default 3k, 3k+1, 3k+2);
    ParameterError naming ``what`` if the plugin is not usable here."""
    mod = module()
    if mod is None:
        raise ParameterError(f"{what} needs the compiled OpenMM plugin, which is not usable here "
                             f"({status().reason}){advice}")
    n = model.n_nodes
    idx = np.arange(3 * n).reshape(n, 3) if particles is None else np.asarray(particles, int).reshape(n, 3)
    return mod, idx


def smk_force(model, radius, particles=None):
    """The SMK step energy of a model as a compiled ``SMKForce``.

    Parameters
    ----------
    model : RodModel
        Its stiffness (n_steps, 6, 6), intrinsic strains (n_steps, 6), ``ds`` (nm) and closure are used.
    radius : ndarray, shape (n_nodes,)
        Triangle circumradius of every node, nm.
    particles : ndarray of int, shape (n_nodes, 3), optional
        Particle indices of every node (default ``3k, 3k+1, 3k+2``).

    Returns
    -------
    SMKForce
        An ``openmm.Force`` (in force group ``GROUPS["elastic"]``) to add to the System.

    Raises
    ------
    ParameterError
        If the plugin is not usable here (the message says why).
    """
    from dnarod.engines.openmm.forces import GROUPS  # loads OpenMM

    mod, idx = _module_and_particles(model, particles, "elastic='plugin'", "; use elastic='auto' or 'fast'")
    n = model.n_nodes
    f = mod.SMKForce()
    for k in range(n):
        f.addNode(int(idx[k, 0]), int(idx[k, 1]), int(idx[k, 2]), float(radius[k]))
    K = np.asarray(model.params.stiffness, float)
    xi0 = np.asarray(model.params.intrinsic, float)
    for k in range(n - 1):
        f.addStep(k, k + 1, K[k].ravel().tolist(), xi0[k].tolist(), False)
    if model.closure is not None:
        f.addStep(n - 1, 0, K[n - 1].ravel().tolist(), xi0[n - 1].tolist(), True)
        f.setClosure(np.asarray(model.closure.Q, float).ravel().tolist(), np.asarray(model.closure.t, float).tolist())
    f.setDs(float(model.ds))
    f.setForceGroup(GROUPS["elastic"])
    f.setName("dnarod elastic (plugin)")
    return f


def rigid_body_integrator(radius, dt, temperature=300.0, friction=1.0, seed=0, particles=None):
    """The compiled constraint-free integrator of rigid three-particle nodes.

    Symplectic splitting of :mod:`dnarod.engines.lax.splitting` (kick, drift, exact free-rotor sub-flows
    R1(h/2) R2(h/2) R3(h) R2(h/2) R1(h/2)) in the leapfrog form of OpenMM's LangevinMiddleIntegrator:
    stored velocities are half a step behind the positions, ``V(dt) A(dt)`` for NVE (``friction=0``) and
    ``V(dt) A(dt/2) O(dt) A(dt/2)`` for Langevin (BAOAB). Triangles stay exactly rigid without constraints;
    zero-mass (clamped) nodes stay put. The SMK loads of an ``SMKForce`` on the same nodes are evaluated
    inside the integrator; other forces through OpenMM. Its random-number state is checkpointed with the
    Context. On a GPU platform with the plugin's device kernels (:func:`device_kernel`) whole steps run on the
    device (forces from OpenMM there, random numbers from OpenMM's generator).

    Parameters
    ----------
    radius : ndarray, shape (n_nodes,)
        Triangle circumradius, nm.
    dt : float
        ps.
    temperature : float
        K.
    friction : float
        1/ps; 0 gives NVE.
    seed : int
        Random-number seed (0: from the operating system).
    particles : ndarray of int, shape (n_nodes, 3), optional
        Particle indices of every node (default ``3k, 3k+1, 3k+2``).

    Returns
    -------
    RigidBodyIntegrator
        An ``openmm.Integrator``.
    """
    mod = module()
    if mod is None:
        raise ParameterError(f"the rigid-body integrator needs the compiled OpenMM plugin, which is not usable "
                             f"here ({status().reason})")
    radius = np.asarray(radius, float)
    n = radius.size
    idx = np.arange(3 * n).reshape(n, 3) if particles is None else np.asarray(particles, int).reshape(n, 3)
    integ = mod.RigidBodyIntegrator(float(dt), float(temperature), float(friction))
    for k in range(n):
        integ.addNode(int(idx[k, 0]), int(idx[k, 1]), int(idx[k, 2]), float(radius[k]))
    integ.setRandomNumberSeed(int(seed) % 2**31)
    return integ


def node_pair_force(model, numbers, particles=None):
    """The non-local terms of :mod:`dnarod.engines.openmm.nonbonded` (WCA + shifted Debye-Hueckel between node centres,
    chain exclusions) as a compiled ``NodePairForce`` (Verlet list in C++).

    Parameters
    ----------
    model : RodModel
        Its node count and closure (circular chains wrap the exclusions) are used.
    numbers : dict
        From :meth:`dnarod.physics.nonbonded.NonbondedSettings.resolve` (eps kJ/mol, sigma nm, rc_wca nm,
        a_dh kJ/mol nm, kappa 1/nm, rc_dh nm, n_exclude).
    particles : ndarray of int, shape (n_nodes, 3), optional
        Particle indices of every node (default ``3k, 3k+1, 3k+2``).

    Returns
    -------
    NodePairForce
        In force group ``GROUPS["nonbonded"]``.
    """
    from dnarod.engines.openmm.forces import GROUPS  # loads OpenMM

    mod, idx = _module_and_particles(model, particles, "the compiled non-bonded force")
    n = model.n_nodes
    f = mod.NodePairForce()
    for k in range(n):
        f.addNode(int(idx[k, 0]), int(idx[k, 1]), int(idx[k, 2]))
    v = numbers
    f.setParameters(float(v["eps"]), float(v["sigma"]), float(v["rc_wca"]), float(v["a_dh"]), float(v["kappa"]),
                    float(v["rc_dh"]), int(v["n_exclude"]), model.closure is not None)
    f.setForceGroup(GROUPS["nonbonded"])
    f.setName("dnarod nonbonded (WCA + Debye-Hueckel, plugin)")
    return f


class ElasticEnergy:
    """Per-term energy of the last evaluation of an ``SMKForce`` (the interface of
    :class:`dnarod.engines.openmm.forces.ElasticCallback` that :class:`~dnarod.engines.openmm.simulation.RodSimulation`
    reads, so its per-term energies need no extra force evaluations)."""

    def __init__(self, force):
        self.force = force

    @property
    def last_energy(self):
        """kJ/mol."""
        return self.force.getLastEnergy()


class PairEnergies:
    """``(E_wca, E_dh)`` of the last evaluation of a ``NodePairForce`` (the interface of
    :class:`dnarod.engines.openmm.nonbonded.NonbondedCallback` read by ``RodSimulation``)."""

    def __init__(self, force):
        self.force = force

    @property
    def last(self):
        """kJ/mol."""
        return self.force.getLastWca(), self.force.getLastDebyeHuckel()
