"""The compiled plugin's device (Common-compute) kernels on OpenMM's OpenCL platform (pocl on a CPU in CI; any
OpenCL device elsewhere): SMKForce and the rigid-body integrator's step.

References: dnarod.core.energy.loads (numpy analytic loads) and the plugin's host code on the Reference platform;
for trajectories, the Python-callback path on the Reference platform with the same VerletIntegrator + SETTLE,
and the rigid-body integrator's host steps on Reference for its device steps; the Maxwell-Boltzmann variances
for its thermostat.
Skipped with the reason when OpenCL or the kernel library is missing, except under ``CI=true`` (``.ci/run``
installs pocl and the OpenCL headers as root on Debian), where either is a failure.

Tolerances (stated, not tuned to pass):
* ``double``: energy 1e-10 relative (1e-12 against the host code), node forces, torques and particle forces 1e-10
  of the largest (forces are accumulated in OpenMM's 64-bit fixed point, resolution 2^-32 kJ/mol/nm);
* ``mixed`` and ``single`` (forces in single precision): 2e-5 relative (single epsilon 6e-8 times the ~10^2
  operations per step; measured 3e-7 to 2e-6).
"""
import io
import os

import numpy as np
import openmm
import pytest

from dnarod.core.energy import loads
from dnarod.core.forcefield import load_forcefield
from dnarod.core.model import RodModel
from dnarod.engines.openmm import particles as P
from dnarod.engines.openmm import plugin
from dnarod.core.parameters import StepParameters

from test_plugin import assert_equal_loads, plugin_loads, random_model

TOL = {"double": 1e-10, "mixed": 2e-5, "single": 2e-5}
CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")


def _fail_or_skip(why):
    if CI:
        pytest.fail(f"CI: {why}")
    pytest.skip(why)


@pytest.fixture(scope="module")
def mod():
    st = plugin.status()
    if not st.available:
        _fail_or_skip(f"compiled plugin not usable: {st.reason}")
    names = [openmm.Platform.getPlatform(i).getName() for i in range(openmm.Platform.getNumPlatforms())]
    if "OpenCL" not in names:
        why = "; ".join(openmm.Platform.getPluginLoadFailures()) or "install pocl-opencl-icd"
        _fail_or_skip(f"OpenMM has no OpenCL platform: {why}")
    ok, why = plugin.device_kernel("OpenCL")
    if not ok:
        _fail_or_skip(f"no OpenCL kernel of the plugin: {why}")
    return plugin.module()


def opencl_context(model, precision, integrator=None):
    r = P.triangle_radius(model.mass, model.inertia)
    system = openmm.System()
    for m in np.repeat(model.mass / 3, 3):
        system.addParticle(m)
    force = plugin.smk_force(model, r)
    system.addForce(force)
    ctx = openmm.Context(system, integrator or openmm.VerletIntegrator(0.001),
                         openmm.Platform.getPlatformByName("OpenCL"), {"Precision": precision})
    ctx.setPositions(P.particle_positions(model.positions, model.frames, r))
    return ctx, force


@pytest.mark.parametrize("circular", [False, True])
@pytest.mark.parametrize("precision", ["double", "mixed", "single"])
def test_device_kernel_equals_dnarod_energy(mod, precision, circular):
    """Random full 6x6 K and intrinsic strains per step, far from the intrinsic shape, open and circular (screw
    closure): energy, node forces and torques equal dnarod.core.energy; the host code never ran."""
    model = random_model(21 + circular, circular=circular)
    want = loads(model.positions, model.frames, model.params, model.ds, model.closure)
    assert want[0] > 1.0
    ctx, force = opencl_context(model, precision)
    assert force.usesDeviceKernel(ctx)
    assert_equal_loads(plugin_loads(ctx), want, TOL[precision])
    assert force.getLastEnergy() == 0.0  # the host evaluation (which records it) was not used


def test_particle_forces_equal_reference_plugin(mod):
    """Per-particle forces in double precision equal the plugin's host code on the Reference platform (the
    same spreading of node loads over the triangle)."""
    model = random_model(5, circular=True)
    ctx, _ = opencl_context(model, "double")
    from test_plugin import context

    ref, rforce = context(model, "Reference")
    assert not rforce.usesDeviceKernel(ref)
    got = ctx.getState(getForces=True, getEnergy=True)
    want = ref.getState(getForces=True, getEnergy=True)
    f, f0 = got.getForces(asNumpy=True)._value, want.getForces(asNumpy=True)._value
    assert np.max(np.abs(f - f0)) <= 1e-10 * np.max(np.abs(f0))
    E, E0 = got.getPotentialEnergy()._value, want.getPotentialEnergy()._value
    assert abs(E - E0) <= 1e-12 * abs(E0)


def test_sequence_model_and_parameter_update_on_device(mod):
    """Olson sequence-dependent parameters: zero loads at the intrinsic shape; after setStepParameters +
    updateParametersInContext the device uses the new K and xi0."""
    seq = "CGCGAATTCGCGATATGC"
    olson = load_forcefield("olson1998").model_from_sequence(seq)
    ctx, force = opencl_context(olson, "double")
    E, F, tau = plugin_loads(ctx)
    assert abs(E) < 1e-9 and np.max(np.abs(F)) < 1e-7 and np.max(np.abs(tau)) < 1e-7
    bent = random_model(5, sequence=seq)
    bent = RodModel(bent.positions, bent.frames, olson.params, olson.ds, olson.mass, olson.inertia)
    ctx, force = opencl_context(bent, "double")
    assert_equal_loads(plugin_loads(ctx), loads(bent.positions, bent.frames, bent.params, bent.ds), 1e-10)
    K = bent.params.stiffness.copy()
    xi0 = bent.params.intrinsic.copy()
    K[4] *= 1.9
    xi0[7] += np.array([0.1, -0.2, 0.3, 0.05, -0.05, 0.02])
    for k in (4, 7):
        force.setStepParameters(k, K[k].ravel().tolist(), xi0[k].tolist())
    force.updateParametersInContext(ctx)
    want = loads(bent.positions, bent.frames, StepParameters(K, xi0), bent.ds)
    assert abs(want[0] - loads(bent.positions, bent.frames, bent.params, bent.ds)[0]) > 1.0
    assert_equal_loads(plugin_loads(ctx), want, 1e-10)


def test_auto_takes_the_device_kernels_on_opencl(mod, capsys):
    """elastic='auto' on OpenCL: the plugin's SMKForce and rigid-body integrator both on the device, said once;
    without the kernels it falls back to the portable expression."""
    from dnarod.engines.openmm.simulation import RodSimulation
    from dnarod.engines.openmm.system import choose_elastic

    plugin._DEVICE_ANNOUNCED.discard("OpenCL")
    assert choose_elastic("auto", "OpenCL") == "plugin"
    assert choose_elastic("auto", "OpenCL") == "plugin"
    err = capsys.readouterr().err
    assert err.count("OpenCL kernels (SMK force and rigid-body steps on the device") == 1
    model = load_forcefield("dna-default").model_from_sequence("ACGTTGCAAC" * 2)
    sim = RodSimulation.create(model, platform="OpenCL", precision="mixed", temperature=300.0, seed=3, nonbonded=False)
    assert sim.rs.elastic == "plugin" and sim.rs.device
    assert isinstance(sim.integrator, mod.RigidBodyIntegrator) and sim.integrator.usesDeviceKernel()
    assert not sim.integrator.usesFusedElasticForce()
    smk = [f for f in (sim.rs.system.getForce(i) for i in range(sim.rs.system.getNumForces()))
           if mod.SMKForce.isinstance(f)]
    assert len(smk) == 1 and mod.SMKForce.cast(smk[0]).usesDeviceKernel(sim.context)
    sim.advance(200)
    e = sim.energies()
    assert np.isfinite(e["elastic"]) and e["elastic"] > 0 and 10.0 < e["temperature"] < 1000.0
    c, f = sim.node_pose()
    assert np.isfinite(c).all()
    # without the kernel: the portable path, said once
    saved = plugin._DEVICE["OpenCL"]
    try:
        plugin._DEVICE["OpenCL"] = (False, "its OpenCL kernel library was not built: test")
        plugin._DEVICE_ANNOUNCED.discard("OpenCL")
        assert choose_elastic("auto", "OpenCL") == "portable"
        assert "compiled OpenMM plugin not used on OpenCL (its OpenCL kernel library was not built: test)" in \
            capsys.readouterr().err
    finally:
        plugin._DEVICE["OpenCL"] = saved


def test_nve_settle_trajectory_equals_callback_path(mod):
    """OpenMM's VerletIntegrator + SETTLE in double precision: the SMK device kernel on OpenCL follows the same
    trajectory as the Python-callback path on the Reference platform (same integrator, same forces). Measured after
    100 steps: 5e-9 nm / 3e-8 in the frames; OpenMM's own CustomCompoundBondForce on OpenCL differs from Reference
    by 4e-9 nm / 6e-9 in the same run (the platforms' SETTLE and summation differ; the rounding grows with time)."""
    from dnarod.engines.openmm.simulation import RodSimulation
    from dnarod.engines.openmm.system import build_system

    model = random_model(8, scale=0.02, rot=0.05)
    ref = RodSimulation.create(model, integrator="verlet", temperature=300.0, elastic="fast", platform="Reference",
                               seed=4,
                        nonbonded=False, dt=0.01)
    st = ref.context.getState(getPositions=True, getVelocities=True)
    rs = build_system(model, "OpenCL", "plugin", nonbonded=False)
    assert rs.device
    integ = openmm.VerletIntegrator(0.01)
    integ.setConstraintTolerance(1e-8)
    ctx = openmm.Context(rs.system, integ, openmm.Platform.getPlatformByName("OpenCL"), {"Precision": "double"})
    ctx.setPositions(st.getPositions())
    ctx.setVelocities(st.getVelocities())
    ref.advance(100)
    integ.step(100)
    c0, f0 = ref.node_pose()
    c, f = P.node_poses(ctx.getState(getPositions=True).getPositions(asNumpy=True)._value)
    assert np.max(np.abs(c - c0)) < 1e-7
    assert np.max(np.abs(f - f0)) < 2e-7


@pytest.mark.parametrize("precision, tol", [("double", 1e-10), ("mixed", 1e-6), ("single", 1e-4)])
def test_rigid_body_steps_on_device_equal_host(mod, precision, tol):
    """NVE: the rigid-body integrator's device steps on OpenCL follow its host steps on Reference (the same
    splitting; measured after 100 steps: 3e-13 nm / 5e-13 in the frames in double, 2e-8 / 4e-8 mixed, 2e-6 / 3e-6
    single), and keep every triangle rigid."""
    from dnarod.engines.openmm.simulation import RodSimulation
    from dnarod.engines.openmm.system import build_system

    model = random_model(8, scale=0.02, rot=0.05)
    ref = RodSimulation.create(model, integrator="verlet", temperature=300.0, elastic="plugin", platform="Reference",
                               seed=4,
                        nonbonded=False, dt=0.01)
    st = ref.context.getState(getPositions=True, getVelocities=True)
    rs = build_system(model, "OpenCL", "plugin", nonbonded=False)
    integ = plugin.rigid_body_integrator(rs.radius, 0.01, 300.0, 0.0, 7)
    ctx = openmm.Context(rs.system, integ, openmm.Platform.getPlatformByName("OpenCL"), {"Precision": precision})
    assert integ.usesDeviceKernel()
    ctx.setPositions(st.getPositions())
    ctx.setVelocities(st.getVelocities())
    ref.advance(100)
    integ.step(100)
    c0, f0 = ref.node_pose()
    p = ctx.getState(getPositions=True).getPositions(asNumpy=True)._value
    c, f = P.node_poses(p)
    assert np.max(np.abs(c - c0)) < tol
    assert np.max(np.abs(f - f0)) < tol
    tri = p.reshape(-1, 3, 3)
    side = np.linalg.norm(tri[:, 0] - tri[:, 1], axis=1)
    assert np.max(np.abs(side - np.sqrt(3) * rs.radius)) < (1e-12 if precision == "double" else 1e-5)
    assert np.max(np.abs(c - model.positions)) > 1e-4  # the nodes did move


def test_rigid_body_langevin_on_device(mod):
    """Langevin on the device: a checkpoint repeats bit for bit (random numbers from OpenMM's generator, saved
    with the Context), and node velocities and angular velocities have the Maxwell-Boltzmann variances kT/m,
    kT/J_a (400 samples of 30 nodes 10 steps apart at friction 5/ps: within 10%; measured 0.97-1.02)."""
    from dnarod.engines.openmm.system import build_system
    from dnarod.core.units import kT as kT_of

    model = load_forcefield("dna-default").model_from_sequence("ACGTTGCAAC" * 3)
    rs = build_system(model, "OpenCL", "plugin", nonbonded=False)
    integ = plugin.rigid_body_integrator(rs.radius, 0.02, 300.0, 5.0, 11)
    ctx = openmm.Context(rs.system, integ, openmm.Platform.getPlatformByName("OpenCL"), {"Precision": "mixed"})
    ctx.setPositions(P.particle_positions(model.positions, model.frames, rs.radius))
    assert integ.usesDeviceKernel()
    integ.step(500)
    blob = ctx.createCheckpoint()
    integ.step(50)
    a = ctx.getState(getPositions=True, getVelocities=True)
    ctx.loadCheckpoint(blob)
    integ.step(50)
    b = ctx.getState(getPositions=True, getVelocities=True)
    assert np.array_equal(a.getPositions(asNumpy=True)._value, b.getPositions(asNumpy=True)._value)
    assert np.array_equal(a.getVelocities(asNumpy=True)._value, b.getVelocities(asNumpy=True)._value)
    V, W = [], []
    for _ in range(400):
        integ.step(10)
        s = ctx.getState(getPositions=True, getVelocities=True)
        v, w = P.node_velocities(s.getPositions(asNumpy=True)._value, s.getVelocities(asNumpy=True)._value)
        V.append(v)
        W.append(w)
    kT = kT_of(300.0)
    rv = (np.var(V, axis=0) * model.mass[:, None] / kT).mean(axis=0)
    rw = (np.var(W, axis=0) * model.inertia / kT).mean(axis=0)
    assert np.all(np.abs(rv - 1) < 0.1) and np.all(np.abs(rw - 1) < 0.1), (rv, rw)


def test_checkpoint_round_trip_on_device(mod):
    """A Langevin + SETTLE run on the device from a checkpoint repeats bit for bit (device forces are summed in
    fixed point, so they do not depend on the order of the atomic additions)."""
    from dnarod.engines.openmm.system import build_system

    model = random_model(6, scale=0.02, rot=0.05)
    rs = build_system(model, "OpenCL", "plugin", nonbonded=False)
    assert rs.device and rs.system.getNumConstraints() == 3 * model.n_nodes
    integ = openmm.LangevinMiddleIntegrator(300.0, 1.0, 0.005)
    integ.setRandomNumberSeed(17)
    ctx = openmm.Context(rs.system, integ, openmm.Platform.getPlatformByName("OpenCL"), {"Precision": "mixed"})
    ctx.setPositions(P.particle_positions(model.positions, model.frames, rs.radius))
    ctx.setVelocitiesToTemperature(300.0, 5)
    integ.step(20)
    blob = ctx.createCheckpoint()
    integ.step(30)
    a = ctx.getState(getPositions=True, getVelocities=True, getEnergy=True)
    ctx.loadCheckpoint(blob)
    integ.step(30)
    b = ctx.getState(getPositions=True, getVelocities=True, getEnergy=True)
    assert np.array_equal(a.getPositions(asNumpy=True)._value, b.getPositions(asNumpy=True)._value)
    assert np.array_equal(a.getVelocities(asNumpy=True)._value, b.getVelocities(asNumpy=True)._value)
    assert a.getPotentialEnergy()._value == b.getPotentialEnergy()._value
    assert np.isfinite(a.getPotentialEnergy()._value)


def test_build_record_names_device_kernels(mod):
    """The build record lists the device kernels built and the reason for the others; unknown platforms say so."""
    from dnarod._plugin import _build_info

    assert "OpenCL" in _build_info.DEVICE_KERNELS
    assert "CUDA" in _build_info.DEVICE_KERNELS or _build_info.DEVICE_KERNELS_NOT_BUILT["CUDA"]
    ok, why = plugin.device_kernel("HIP")
    assert not ok and "no device kernel for the HIP platform" in why
    buf = io.StringIO()
    plugin._DEVICE_ANNOUNCED.discard("CUDA")
    plugin.announce_device("CUDA", buf)
    plugin.announce_device("CUDA", buf)
    out = buf.getvalue()
    assert out.count("\n") == 1
    if "CUDA" not in _build_info.DEVICE_KERNELS:
        assert "compiled OpenMM plugin not used on CUDA (its CUDA kernel library was not built:" in out


@pytest.mark.parametrize("precision", ["double", "single"])
def test_cayley_limit_gives_nan_energy_on_device(mod, precision):
    """A step rotated by 180 degrees (the Cayley limit): NaN energy and no loads from that step, as the host code."""
    from dnarod.core.rotations import rotation_about_axis

    model = random_model(4, scale=0.0, rot=0.0)
    frames = model.frames.copy()
    frames[3] = frames[2] @ rotation_about_axis(np.array([1.0, 0.0, 0.0]), np.pi)
    ctx, force = opencl_context(model, precision)
    ctx.setPositions(P.particle_positions(model.positions, frames, P.triangle_radius(model.mass, model.inertia)))
    st = ctx.getState(getEnergy=True, getForces=True)
    assert force.usesDeviceKernel(ctx)
    assert np.isnan(st.getPotentialEnergy()._value)
    assert np.isfinite(st.getForces(asNumpy=True)._value).all()


def test_full_model_on_the_device_path(mod):
    """Non-local terms on (NodePairForce, host code on this path): at the same state the per-term energies on
    OpenCL equal the plugin on Reference, and a short Langevin run on the device stays finite."""
    from dnarod.engines.openmm.simulation import RodSimulation

    # 30 bp bent on three quarters of a circle of radius 2.16 nm: non-excluded node pairs 3.3-4.3 nm apart,
    # some inside the Debye-Hueckel cutoff, so the non-local energy is not zero
    base = load_forcefield("dna-default").model_from_sequence("ACGTTGCAAC" * 3)
    R = 40 * base.ds / (2 * np.pi)
    phi = np.arange(base.n_nodes) * base.ds / R
    cos, sin, zero = np.cos(phi), np.sin(phi), np.zeros_like(phi)
    pos = R * np.stack([cos, sin, zero], axis=1)
    d1, d2, d3 = np.stack([-cos, -sin, zero], 1), np.stack([zero, zero, zero + 1], 1), np.stack([-sin, cos, zero], 1)
    model = base.with_pose(pos, np.stack([d1, d2, d3], axis=2))
    sims = [RodSimulation.create(model, platform=p, precision=q, temperature=300.0, seed=2, elastic="plugin")
            for p, q in (("Reference", None), ("OpenCL", "double"))]
    assert sims[1].rs.device and sims[1].integrator.usesDeviceKernel() and not sims[0].rs.device
    e = [s.energies() for s in sims]
    for term in ("elastic", "nonbonded"):
        assert abs(e[0][term] - e[1][term]) <= 1e-9 * max(1.0, abs(e[0][term])), (term, e)
    assert e[0]["nonbonded"] > 0.0 and e[0]["elastic"] > 1.0
    sims[1].advance(100)
    assert np.isfinite(sims[1].energies()["potential"])
