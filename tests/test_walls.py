"""Tweezers walls (dnarod.engines.openmm.walls): the compiled WallForce and the numba PythonForce against the OpenMM
Custom-force reference and a numpy transcription of the energy, finite differences, the skipped end nodes,
serialization, a reinitialised Context, the same dynamics, and the energy group that reports them."""
import copy

import numpy as np
import openmm
import pytest

from dnarod.engines.openmm import walls
from dnarod.engines.openmm.forces import GROUPS

needs_plugin = pytest.mark.skipif(not walls.compiled_walls_available(),
                                  reason="compiled plugin with WallForce not built")
FAST_FORMS = [pytest.param("compiled", marks=needs_plugin), "numba"]
BUILD = {"compiled": walls.wall_forces_compiled, "numba": walls.wall_forces_numba}
#: every form usable here (the compiled one only where the plugin is built)
FORMS = [f for f in ("compiled", "numba", "reference") if f != "compiled" or walls.compiled_walls_available()]

N, Z0, K, SKIP = 24, 0.3, 100.0, 3


def wall_configuration(n=N, seed=0):
    """Particle positions (3n, 3) nm of a wavy chain along +z whose particles cross both walls: some of nodes
    skip.. below the surface, some of nodes ..n-1-skip above the last node's centroid, and the skipped end
    nodes across their walls too (they must feel nothing)."""
    rng = np.random.default_rng(seed)
    c = np.zeros((n, 3))
    c[:, 2] = Z0 + 0.34 * np.arange(n)
    c[:, :2] = rng.normal(scale=0.5, size=(n, 2))
    p = np.repeat(c, 3, axis=0) + rng.normal(scale=0.3, size=(3 * n, 3))
    zc = lambda: p[3 * (n - 1):, 2].mean()  # noqa: E731
    p[3 * 4:3 * 7, 2] = Z0 - rng.uniform(0.05, 0.6, size=9)  # nodes 4-6 below the surface
    p[0:3 * SKIP, 2] = Z0 - 0.5  # skipped at the surface: no force
    top = zc()
    p[3 * 15:3 * 18, 2] = top + rng.uniform(0.05, 0.6, size=9)  # nodes 15-17 above the bead plane
    p[3 * (n - SKIP):3 * (n - 1), 2] = top + 0.4  # skipped at the bead (the last node itself stays put)
    p[3 * (n - SKIP):3 * (n - 1), 2] += 0.0
    return p


def evaluate(forces, pos, platform="Reference", groups=None):
    """(energy kJ/mol, forces (3n, 3) kJ/mol/nm) of ``forces`` alone at ``pos``."""
    s = openmm.System()
    for _ in range(len(pos)):
        s.addParticle(1.0)
    for f in forces:
        s.addForce(copy.deepcopy(f))
    props = {"Threads": "1"} if platform == "CPU" else {}
    ctx = openmm.Context(s, openmm.VerletIntegrator(0.001), openmm.Platform.getPlatformByName(platform), props)
    ctx.setPositions(pos)
    st = ctx.getState(getEnergy=True, getForces=True, **({} if groups is None else dict(groups=groups)))
    return st.getPotentialEnergy().value_in_unit(openmm.unit.kilojoule_per_mole), \
        st.getForces(asNumpy=True).value_in_unit(openmm.unit.kilojoule_per_mole / openmm.unit.nanometer)


@pytest.mark.parametrize("form", FAST_FORMS)
@pytest.mark.parametrize("platform", ["Reference", "CPU"])
def test_fast_walls_equal_the_custom_force_reference(platform, form):
    pos = wall_configuration()
    e_ref, f_ref = evaluate(walls.wall_forces_reference(N, Z0, K, SKIP), pos, platform)
    e, f = evaluate(BUILD[form](N, Z0, K, SKIP), pos, platform)
    es, eb, fz = walls.wall_energy(pos[:, 2], N, Z0, K, SKIP)
    assert es > 1.0 and eb > 1.0  # both walls are touched
    assert e == pytest.approx(e_ref, rel=1e-10) and e == pytest.approx(es + eb, rel=1e-12)
    scale = np.abs(f_ref).max()
    assert np.abs(f - f_ref).max() < 1e-10 * scale
    assert np.abs(f[:, 2] - fz).max() < 1e-12 * scale and not f[:, :2].any()  # z forces only
    # the skipped end nodes feel nothing, though they are across their walls; the last node gets the reaction
    assert not f[:3 * SKIP].any() and not f[3 * (N - SKIP):3 * (N - 1)].any()
    d = np.maximum(0.0, pos[0:3 * (N - SKIP):3, 2] - pos[3 * (N - 1):, 2].mean())
    np.testing.assert_allclose(f[3 * (N - 1):, 2], K * d.sum() / 3.0, rtol=1e-12)
    # per-wall energies of the last evaluation, as the two reference forces report them one by one
    ref = walls.wall_forces_reference(N, Z0, K, SKIP)
    ref[1].setForceGroup(GROUPS["external"] + 1)
    assert evaluate(ref, pos, platform, groups={GROUPS["external"]})[0] == pytest.approx(es, rel=1e-10)
    assert evaluate(ref, pos, platform, groups={GROUPS["external"] + 1})[0] == pytest.approx(eb, rel=1e-10)


@pytest.mark.parametrize("form", FAST_FORMS)
def test_fast_walls_finite_differences(form):
    """Central differences of the energy match the forces on every particle that touches a wall."""
    pos = wall_configuration(seed=1)
    s = openmm.System()
    for _ in range(3 * N):
        s.addParticle(1.0)
    s.addForce(BUILD[form](N, Z0, K, SKIP)[0])
    ctx = openmm.Context(s, openmm.VerletIntegrator(0.001), openmm.Platform.getPlatformByName("Reference"))

    def energy(p):
        ctx.setPositions(p)
        return ctx.getState(getEnergy=True).getPotentialEnergy().value_in_unit(openmm.unit.kilojoule_per_mole)

    _, F = evaluate(list(s.getForces()), pos)
    h = 1e-6
    touched = np.flatnonzero(F[:, 2])
    assert len(touched) >= 10
    for i in list(touched) + [0, 3 * N - 1]:
        for a in range(3):
            pp, pm = pos.copy(), pos.copy()
            pp[i, a] += h
            pm[i, a] -= h
            fd = -(energy(pp) - energy(pm)) / (2 * h)
            assert fd == pytest.approx(F[i, a], rel=1e-6, abs=1e-6)


@pytest.mark.parametrize("form", FAST_FORMS)
def test_wall_force_serializes_and_reports_its_group(form):
    f = BUILD[form](N, Z0, K, SKIP)[0]
    assert f.getForceGroup() == GROUPS["external"]
    s = openmm.System()
    for _ in range(3 * N):
        s.addParticle(1.0)
    s.addForce(f)
    copy_ = openmm.XmlSerializer.deserialize(openmm.XmlSerializer.serialize(s))
    pos = wall_configuration(seed=2)
    e1, f1 = evaluate([s.getForce(0)], pos)
    e2, f2 = evaluate([copy_.getForce(0)], pos)
    assert e1 == e2 and np.array_equal(f1, f2) and e1 > 0
    assert copy_.getForce(0).getForceGroup() == GROUPS["external"]
    # the energy sits in the "external" group only
    assert evaluate([f], pos, groups={GROUPS["elastic"], GROUPS["nonbonded"]})[0] == 0.0


@needs_plugin
def test_wall_form_choice_and_bad_input():
    from dnarod.core.errors import ParameterError

    assert type(walls.wall_forces(N, Z0, K, SKIP, platform="CPU")[0]).__name__ == "WallForce"
    assert type(walls.wall_forces(N, Z0, K, SKIP, platform="Reference")[0]).__name__ == "WallForce"
    # GPU platforms keep the Custom forces (they run on the device)
    names = [type(f).__name__ for f in walls.wall_forces(N, Z0, K, SKIP, platform="OpenCL")]
    assert names == ["CustomExternalForce", "CustomCentroidBondForce"]
    with pytest.raises(ParameterError, match="skip"):
        walls.wall_forces(N, Z0, K, -1)
    with pytest.raises(ParameterError, match="skip"):
        walls.wall_forces(N, Z0, K, N)
    with pytest.raises(ParameterError, match="form"):
        walls.wall_forces(N, Z0, K, SKIP, form="lepton")


def test_without_the_plugin_the_walls_fall_back_to_numba(monkeypatch):
    """Where the plugin (or its WallForce) is not usable, the automatic form is the numba PythonForce on the host
    platforms and the Custom-force reference on the others."""
    monkeypatch.setattr(walls, "compiled_walls_available", lambda: False)
    for plat in ("CPU", "Reference"):
        assert [type(f).__name__ for f in walls.wall_forces(N, Z0, K, SKIP, platform=plat)] == ["PythonForce"]
    names = [type(f).__name__ for f in walls.wall_forces(N, Z0, K, SKIP, platform="OpenCL")]
    assert names == ["CustomExternalForce", "CustomCentroidBondForce"]
    from dnarod.core.errors import ParameterError

    with pytest.raises(ParameterError, match="compiled OpenMM plugin"):
        walls.wall_forces(N, Z0, K, SKIP, form="compiled")


def _member_sim(elastic, platform="Reference", walls_now=True, form="auto"):
    from dnarod.core.forcefield import load_forcefield
    from dnarod.physics.loads import Clamp, PullingForce, Walls
    from dnarod.engines.openmm.simulation import RodSimulation
    from dnarod.workflows.protocols import tweezers as tw
    from dnarod.core.units import PN

    model = tw.strained_helix(load_forcefield("dna-default").model_from_sequence(n_nodes=N), 2.0, 0.0)
    loads = [Clamp(0), PullingForce(-1, [0.0, 0.0, 2.0 * PN])]
    if form == "load":  # the tweezers set-up's Walls load, built by the engine
        loads.append(Walls())
        extra = ()
    else:
        extra = walls.wall_forces(N, float(model.positions[0, 2]), 100.0, 3, platform=platform, form=form) \
            if walls_now else ()
    sim = RodSimulation.create(model, platform=platform, elastic=elastic, nonbonded=False, loads=loads, seed=1,
                        extra_forces=extra)
    return sim, model


@pytest.mark.parametrize("elastic, platform", [("auto", "Reference"), ("auto", "CPU"), ("fast", "Reference"),
                                               ("portable", "Reference")])
def test_walls_in_a_member_simulation_report_in_external(elastic, platform):
    """With every elastic path, the walls' energy is in the "external" term: pushing nodes through both walls
    raises it by exactly the numpy wall energy (pulling-force energy removed), with either wall form."""
    from dnarod.engines.openmm.particles import particle_positions

    got = {}
    for form in (*FORMS, "load"):
        sim, model = _member_sim(elastic, platform, form=form)
        p = particle_positions(model.positions, model.frames, sim.rs.radius).reshape(-1, 3).copy()
        z0 = float(model.positions[0, 2])
        top = p[3 * (N - 1):3 * N, 2].mean()
        p[3 * 5:3 * 6, 2] = z0 - 0.2  # one node's particles under the surface
        p[3 * 12, 2] = top + 0.3      # one particle over the bead plane
        e_pull0 = sim.energies()["external"]
        sim.context.setPositions(p if sim.rs.image is None else np.vstack([p, np.zeros((3, 3))]))
        sim.invalidate()
        es, eb, _ = walls.wall_energy(p[:3 * N, 2], N, z0, 100.0, 3)
        e_ext = sim.energies()["external"]
        got[form] = e_ext
        assert es > 1.0 and eb > 1.0
        # the pulling force's energy -F z_last did not change (the last node was not moved)
        assert e_ext - e_pull0 == pytest.approx(es + eb, rel=1e-9), (elastic, form, sim.rs.elastic)
    for form in (*FORMS, "load"):
        assert got[form] == pytest.approx(got["reference"], rel=1e-10)


@needs_plugin
@pytest.mark.parametrize("platform", ["Reference", "CPU"])
def test_a_tweezers_member_uses_the_compiled_walls(platform):
    from dnarod.workflows.protocols import tweezers as tw

    m = tw.build_member(dict(n_bp=30, force_pN=2.0, turns=0.2, time_ns=0.01, equilibration_ns=0.005,
                             platform=platform))
    sim = tw._member_simulation(m, m["model"])
    names = [sim.rs.system.getForce(i).getName() for i in range(sim.rs.system.getNumForces())]
    assert "dnarod tweezers walls (surface + bead plane, plugin)" in names
    assert not any(n.startswith("dnarod tweezers surface") or "bead plane" == n[-10:] for n in names)
    wall = sim.rs.system.getForce(names.index("dnarod tweezers walls (surface + bead plane, plugin)"))
    assert wall.getForceGroup() == GROUPS["external"]


@pytest.mark.parametrize("elastic", ["auto", "fast"])
def test_every_form_gives_the_same_dynamics(elastic):
    """From a pose pushed through both walls, 200 Langevin steps (same seed) with the compiled, the numba and the
    Custom-force walls end in the same state (the forces agree to rounding)."""
    from dnarod.engines.openmm.particles import particle_positions

    ends = {}
    for form in FORMS:
        sim, model = _member_sim(elastic, form=form)
        p = particle_positions(model.positions, model.frames, sim.rs.radius).reshape(-1, 3).copy()
        z0 = float(model.positions[0, 2])
        p[3 * 5:3 * 6, 2] -= p[3 * 5:3 * 6, 2].mean() - (z0 - 0.3)  # node 5 under the surface, shape kept
        assert walls.wall_energy(p[:, 2], N, z0, 100.0, 3)[0] > 1.0
        sim.context.setPositions(p)
        sim.invalidate()
        sim.advance(200)
        ends[form] = sim.node_pose()[0]
    for form in FORMS:
        np.testing.assert_allclose(ends[form], ends["reference"], rtol=0, atol=1e-8)
