"""The compiled OpenMM plugin (dnarod.engines.openmm.plugin): SMKForce against dnarod.core.energy, and the fallback.

References: dnarod.core.energy.loads (the numpy analytic loads, checked against finite differences in the core
tests). When the plugin is not built these tests are skipped with the build's reason, except under CI
(``CI=true``), where a missing plugin is a failure.
"""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import openmm
import pytest

from dnarod.core.energy import loads
from dnarod.core.errors import ParameterError
from dnarod.core.forcefield import load_forcefield
from dnarod.core.model import RodModel
from dnarod.engines.openmm import particles as P
from dnarod.engines.openmm import plugin
from dnarod.core.parameters import StepParameters
from dnarod.core.rotations import cayley, rotation_about_axis
from dnarod.core.strains import Closure

ROOT = Path(__file__).resolve().parent.parent


def _require_plugin():
    st = plugin.status()
    if st.available:
        return plugin.module()
    if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
        pytest.fail(f"CI: the compiled plugin must be usable here: {st.reason}")
    print(f"compiled plugin not usable: {st.reason}")
    pytest.skip(f"compiled plugin not usable: {st.reason}")


@pytest.fixture(scope="module")
def mod():
    return _require_plugin()


def random_model(seed, sequence="ACGTTGCAGTCA", circular=False, scale=0.05, rot=0.15):
    """A chain with a random full SPD 6x6 stiffness and intrinsic strains per step, perturbed off its shape."""
    rng = np.random.default_rng(seed)
    base = load_forcefield("dna-default").model_from_sequence(sequence, circular=circular)
    m = base.n_steps
    A = rng.normal(size=(m, 6, 6))
    K = np.einsum("kij,klj->kil", A, A) * 20 + np.eye(6) * 50
    xi0 = base.params.intrinsic + 0.1 * rng.normal(size=base.params.intrinsic.shape)
    closure = None
    if circular:
        axis = np.array([0.3, 0.2, 1.0]) / np.linalg.norm([0.3, 0.2, 1.0])
        closure = Closure(rotation_about_axis(axis, 0.7), np.array([0.1, -0.2, 3.3]))
    pos = base.positions + scale * rng.normal(size=base.positions.shape)
    frm = cayley(rot * rng.normal(size=(base.n_nodes, 3))) @ base.frames
    return RodModel(pos, frm, StepParameters(K, xi0), base.ds, base.mass, base.inertia, closure=closure)


def context(model, platform="Reference"):
    r = P.triangle_radius(model.mass, model.inertia)
    system = openmm.System()
    for m in np.repeat(model.mass / 3, 3):
        system.addParticle(m)
    force = plugin.smk_force(model, r)
    system.addForce(force)
    ctx = openmm.Context(system, openmm.VerletIntegrator(0.001), openmm.Platform.getPlatformByName(platform))
    ctx.setPositions(P.particle_positions(model.positions, model.frames, r))
    return ctx, force


def plugin_loads(ctx):
    st = ctx.getState(getEnergy=True, getForces=True, getPositions=True)
    p = st.getPositions(asNumpy=True)._value
    F, tau = P.particle_forces_to_loads(p, st.getForces(asNumpy=True)._value)
    return st.getPotentialEnergy()._value, F, tau


def assert_equal_loads(got, want, rtol):
    E, F, tau = got
    E0, F0, tau0 = want
    assert abs(E - E0) <= rtol * abs(E0)
    assert np.max(np.abs(F - F0)) <= rtol * np.max(np.abs(F0))
    assert np.max(np.abs(tau - tau0)) <= rtol * np.max(np.abs(tau0))


@pytest.mark.parametrize("circular", [False, True])
@pytest.mark.parametrize("platform", ["Reference", "CPU"])
def test_energy_forces_torques_equal_dnarod_energy(mod, circular, platform):
    model = random_model(11 + circular, circular=circular)
    ctx, _ = context(model, platform)
    want = loads(model.positions, model.frames, model.params, model.ds, model.closure)
    assert want[0] > 1.0  # far from the intrinsic shape: a real test
    assert_equal_loads(plugin_loads(ctx), want, 1e-10)


def test_olson_sequence_model_and_intrinsic_shape(mod):
    model = load_forcefield("olson1998").model_from_sequence("CGCGAATTCGCGATATGC")
    ctx, _ = context(model)
    E, F, tau = plugin_loads(ctx)
    assert abs(E) < 1e-9 and np.max(np.abs(F)) < 1e-8 and np.max(np.abs(tau)) < 1e-8
    bent = random_model(5, sequence="CGCGAATTCGCGATATGC")
    bent = RodModel(bent.positions, bent.frames, model.params, model.ds, model.mass, model.inertia)
    ctx, _ = context(bent)
    assert_equal_loads(plugin_loads(ctx), loads(bent.positions, bent.frames, bent.params, bent.ds), 1e-10)


def test_per_step_parameters_update_in_context(mod):
    model = random_model(2)
    ctx, force = context(model)
    rng = np.random.default_rng(9)
    K = model.params.stiffness.copy()
    xi0 = model.params.intrinsic.copy()
    K[3] *= 1.7
    xi0[5] += 0.2 * rng.normal(size=6)
    for k in (3, 5):
        force.setStepParameters(k, K[k].ravel().tolist(), xi0[k].tolist())
    force.updateParametersInContext(ctx)
    want = loads(model.positions, model.frames, StepParameters(K, xi0), model.ds)
    assert_equal_loads(plugin_loads(ctx), want, 1e-10)


def test_cayley_limit_gives_nan_energy(mod):
    model = random_model(4, scale=0.0, rot=0.0)
    frames = model.frames.copy()
    frames[3] = frames[2] @ rotation_about_axis(np.array([1.0, 0.0, 0.0]), np.pi)  # step 2 at 180 degrees
    ctx, _ = context(model)
    ctx.setPositions(P.particle_positions(model.positions, frames, P.triangle_radius(model.mass, model.inertia)))
    assert np.isnan(ctx.getState(getEnergy=True).getPotentialEnergy()._value)


def test_simulation_on_plugin_path_has_the_callback_paths_energies(mod):
    from dnarod.engines.openmm.simulation import RodSimulation

    model = random_model(8, sequence="ACGTACGTACGTACGTACGTACGTACGTACGTACGTACGT", scale=0.03, rot=0.05)
    still = (np.zeros((model.n_nodes, 3)), np.zeros((model.n_nodes, 3)))
    sims = {el: RodSimulation.create(model, temperature=300.0, platform="Reference", elastic=el, seed=5,
                              initial_velocities=still) for el in ("plugin", "fast")}
    assert sims["plugin"].rs.elastic == "plugin" and sims["plugin"].integrator.usesFusedElasticForce()
    e = {el: s.energies() for el, s in sims.items()}
    for term in ("elastic", "nonbonded", "potential"):
        assert abs(e["plugin"][term] - e["fast"][term]) <= 1e-10 * max(1.0, abs(e["fast"][term]))
    assert e["fast"]["elastic"] > 1.0
    auto = RodSimulation.create(model, temperature=300.0, platform="CPU", seed=5)
    assert auto.rs.elastic == "plugin" and auto.integrator.usesFusedPairForce()


# --- fallback ----------------------------------------------------------------------------------------------
@pytest.fixture
def fresh_status(monkeypatch):
    plugin._reset_for_tests()
    yield monkeypatch
    plugin._reset_for_tests()


def test_switched_off_falls_back_and_says_so_once(fresh_status, capsys):
    from dnarod.engines.openmm.system import build_system

    fresh_status.setenv("DNAROD_PLUGIN", "0")
    model = load_forcefield("dna-default").model_from_sequence("ACGTACGT")
    assert build_system(model, "CPU", "auto", nonbonded=False).elastic == "fast"
    assert build_system(model, "Reference", "auto", nonbonded=False).elastic == "fast"
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["dnarod: compiled OpenMM plugin not used (switched off by DNAROD_PLUGIN=0); "
                   "using the Python-callback path"]
    with pytest.raises(ParameterError, match="elastic='plugin' needs the compiled OpenMM plugin"):
        build_system(model, "CPU", "plugin", nonbonded=False)


def test_abi_mismatch_names_both_versions_and_falls_back(fresh_status, capsys):
    from dnarod._plugin import _build_info
    from dnarod.engines.openmm.system import build_system

    if _build_info.STATUS != "built":
        pytest.skip(f"plugin not built: {_build_info.REASON}")
    fresh_status.setattr(plugin, "_installed_openmm", lambda: "99.0.0.dev-test")
    st = plugin.status()
    assert not st.available
    assert f"built against OpenMM {_build_info.OPENMM_VERSION} but OpenMM 99.0.0.dev-test is installed" in st.reason
    model = load_forcefield("dna-default").model_from_sequence("ACGTACGT")
    assert build_system(model, "CPU", "auto", nonbonded=False).elastic == "fast"
    err = capsys.readouterr().err
    assert "99.0.0.dev-test" in err and _build_info.OPENMM_VERSION in err and "Python-callback path" in err


def test_build_without_compiler_still_installs_and_records_why(tmp_path):
    """The top-level CMake project with no usable C++ compiler: configure succeeds, the package data are
    installed and _build_info.py says the plugin was not built and why."""
    cmake = shutil.which("cmake")
    if cmake is None:
        pytest.skip("no cmake on PATH")
    env = dict(os.environ, CXX=str(tmp_path / "no-such-compiler"))
    build = tmp_path / "build"
    r = subprocess.run([cmake, "-S", str(ROOT), "-B", str(build), f"-DPython_EXECUTABLE={sys.executable}"],
                       env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    info = (build / "_build_info.py").read_text()
    ns = {}
    exec(info, ns)  # noqa: S102 - our own generated file
    assert ns["STATUS"] == "not built"
    assert ns["REASON"].startswith("configuring it failed")
    r = subprocess.run([cmake, "--install", str(build), "--prefix", str(tmp_path / "inst")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "inst/dnarod/_bundled/forcefields/dna-default.toml").is_file()
    assert (tmp_path / "inst/dnarod/_plugin/_build_info.py").is_file()
    assert not list((tmp_path / "inst/dnarod/_plugin").glob("_dnarodplugin*"))


def test_node_pair_force_equals_nonbonded_reference_as_nodes_move(mod):
    """The compiled WCA + Debye-Hueckel (Verlet list) against the all-pairs numpy reference, on a squashed ring
    with many contacts, after small moves (list kept) and large ones (list rebuilt)."""
    from dnarod.physics.nonbonded import NonbondedSettings, nonbonded_reference

    model = load_forcefield("dna-default").ring(n_nodes=120)
    numbers = NonbondedSettings(salt=0.05).resolve(model.ds, 300.0)
    system = openmm.System()
    for _ in range(3 * model.n_nodes):
        system.addParticle(100.0)
    system.addForce(plugin.node_pair_force(model, numbers))
    ctx = openmm.Context(system, openmm.VerletIntegrator(0.001), openmm.Platform.getPlatformByName("Reference"))
    rng = np.random.default_rng(0)
    pos = model.positions * np.array([1.0, 0.25, 1.0]) + 0.3 * rng.normal(size=model.positions.shape)
    for move in (0.0, 0.05, 0.05, 2.0, 0.1):
        pos = pos + move * rng.normal(size=pos.shape)
        ctx.setPositions(P.particle_positions(pos, model.frames, 0.6))
        st = ctx.getState(getEnergy=True, getForces=True, getPositions=True)
        F, tau = P.particle_forces_to_loads(st.getPositions(asNumpy=True)._value, st.getForces(asNumpy=True)._value)
        ew, ed, F0 = nonbonded_reference(pos, True, numbers)
        assert ew > 0 and ed > 0
        assert abs(st.getPotentialEnergy()._value - (ew + ed)) <= 1e-12 * (ew + ed)
        assert np.max(np.abs(F - F0)) <= 1e-12 * np.max(np.abs(F0))
        assert np.max(np.abs(tau)) <= 1e-12 * np.max(np.abs(F0))


def _opencl_available():
    names = [openmm.Platform.getPlatform(i).getName() for i in range(openmm.Platform.getNumPlatforms())]
    return "OpenCL" in names


@pytest.mark.skipif(not _opencl_available(), reason="no OpenCL platform (install pocl-opencl-icd for CPU OpenCL)")
def test_plugin_force_and_integrator_on_opencl(mod):
    """On OpenCL the SMK force (device kernel where built, host code otherwise; the device kernels have their own
    tests in test_plugin_opencl.py) equals dnarod.core.energy to 1e-11 in double precision, 1e-5 in single; the plugin
    path follows the same NVE trajectory as on the CPU platform."""
    model = random_model(11, circular=True)
    want = loads(model.positions, model.frames, model.params, model.ds, model.closure)
    for precision, rtol in (("double", 1e-11), ("single", 1e-5)):
        r = P.triangle_radius(model.mass, model.inertia)
        system = openmm.System()
        for m in np.repeat(model.mass / 3, 3):
            system.addParticle(m)
        system.addForce(plugin.smk_force(model, r))
        ctx = openmm.Context(system, openmm.VerletIntegrator(0.001), openmm.Platform.getPlatformByName("OpenCL"),
                             {"Precision": precision})
        ctx.setPositions(P.particle_positions(model.positions, model.frames, r))
        assert_equal_loads(plugin_loads(ctx), want, rtol)
    from dnarod.engines.openmm.simulation import RodSimulation

    plain = load_forcefield("dna-default").model_from_sequence("ACGTACGTACGT")
    ends = []
    for platform in ("CPU", "OpenCL"):
        sim = RodSimulation.create(plain, integrator="verlet", temperature=300.0, elastic="plugin", platform=platform,
                            seed=4, nonbonded=False, dt=0.02)
        sim.advance(50)
        ends.append(sim.node_pose()[0])
    assert np.max(np.abs(ends[0] - ends[1])) < 1e-4


@pytest.mark.skipif(not _opencl_available(), reason="no OpenCL platform (install pocl-opencl-icd for CPU OpenCL)")
def test_host_code_on_opencl_without_device_kernels(mod):
    """DNAROD_DEVICE_KERNELS=0 (or no kernel library): on OpenCL the plugin runs as host code (SMK force through
    CustomCPPForceImpl, rigid-body steps on host copies), said once, and follows the CPU platform's trajectory."""
    code = """
import numpy as np
from dnarod.core.forcefield import load_forcefield
from dnarod.engines.openmm import plugin
from dnarod.engines.openmm.simulation import RodSimulation
plain = load_forcefield("dna-default").model_from_sequence("ACGTACGTACGT")
ends = []
for platform in ("CPU", "OpenCL"):
    sim = RodSimulation.create(plain, integrator="verlet", temperature=300.0, elastic="plugin", platform=platform,
                        seed=4, nonbonded=False, dt=0.02)
    assert not sim.rs.device and not sim.integrator.usesDeviceKernel()
    sim.advance(50)
    ends.append(sim.node_pose()[0])
assert np.max(np.abs(ends[0] - ends[1])) < 1e-4
plugin.announce_device("OpenCL")
print("host-ok")
"""
    env = dict(os.environ, DNAROD_DEVICE_KERNELS="0")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=600)
    assert p.returncode == 0, p.stderr[-2000:]
    assert "host-ok" in p.stdout
    assert ("compiled OpenMM plugin not used on OpenCL (device kernels switched off by DNAROD_DEVICE_KERNELS=0)"
            in p.stderr)


def test_system_with_plugin_forces_pickles_and_copies(mod):
    """XmlSerializer proxies: a System holding SMKForce and NodePairForce survives pickle and deepcopy with the
    same energy and forces."""
    import copy
    import pickle

    from dnarod.engines.openmm.system import build_system

    model = random_model(3, circular=True)
    rs = build_system(model, "Reference", "plugin", nonbonded=True)
    pos = P.particle_positions(model.positions, model.frames, rs.radius)
    out = []
    for system in (rs.system, pickle.loads(pickle.dumps(rs.system)), copy.deepcopy(rs.system)):
        names = [system.getForce(i).getName() for i in range(system.getNumForces())]
        assert "dnarod elastic (plugin)" in names and "dnarod nonbonded (WCA + Debye-Hueckel, plugin)" in names
        ctx = openmm.Context(system, openmm.VerletIntegrator(0.001), openmm.Platform.getPlatformByName("Reference"))
        ctx.setPositions(pos)
        st = ctx.getState(getEnergy=True, getForces=True)
        out.append((st.getPotentialEnergy()._value, st.getForces(asNumpy=True)._value))
    for E, F in out[1:]:
        assert E == out[0][0] and np.array_equal(F, out[0][1])
