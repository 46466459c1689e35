"""A bare chain (no non-bonded terms: excluded volume and electrostatics both off) runs through every API: the
settings, the OpenMM engine, ``simulate``, the protocols' members (tweezers, rings, nicked rings), the protocol
command (through its ensemble) and the checks that take non-bonded terms. Before, every path but ``simulate``
failed with "n_exclude must be at least 1"."""
import json

import numpy as np
import pytest
from click.testing import CliRunner

from dnarod.cli.main import main
from dnarod.core.errors import ParameterError
from dnarod.physics.nonbonded import NonbondedSettings, member_nonbonded, nonbonded_record

BARE = {"excluded_volume": False, "electrostatics": False}


def test_settings_of_a_bare_chain():
    nb = NonbondedSettings(**BARE)
    assert not nb.active
    numbers = nb.resolve(0.34, 300.0)
    assert numbers["eps"] == 0.0 and numbers["a_dh"] == 0.0 and numbers["cutoff"] == 0.0
    assert numbers["n_exclude"] >= 1
    assert nonbonded_record(nb, 0.34, 300.0) is None
    assert not member_nonbonded({**BARE, "salt_M": 0.15}).active
    from dnarod.core.forcefield import load_forcefield
    from dnarod.engines.openmm.nonbonded import nonbonded_force

    model = load_forcefield("dna-default").model_from_sequence(n_nodes=12)
    force, _ = nonbonded_force(model, nb, 300.0)
    assert force is None
    # an explicit exclusion below 1 is still refused where a term is on
    with pytest.raises(ParameterError, match="n_exclude"):
        NonbondedSettings(n_exclude=0).resolve(0.34, 300.0)


def test_engine_with_bare_settings_equals_engine_without_nonbonded():
    from dnarod.core.forcefield import load_forcefield
    from dnarod.engines.openmm.simulation import RodSimulation

    model = load_forcefield("dna-default").model_from_sequence(n_nodes=40)
    poses = []
    for nb in (NonbondedSettings(**BARE), False):
        sim = RodSimulation.create(model, temperature=300.0, friction=1.0, nonbonded=nb, seed=4, platform="Reference")
        sim.advance(200)
        poses.append(sim.node_pose()[0])
    assert np.array_equal(poses[0], poses[1])  # the same system: no non-bonded force at all


def test_tweezers_ring_and_nicked_members_of_a_bare_chain(tmp_path):
    from dnarod.workflows.protocols.nicked import run_nicked_member
    from dnarod.workflows.protocols.rings import run_ring_member
    from dnarod.workflows.protocols.tweezers import run_member

    r = run_member(dict(n_bp=30, force_pN=1.0, turns=0.0, time_ns=0.02, equilibration_ns=0.005, **BARE),
                   tmp_path / "tweezers")
    assert 0 < r["extension_nm"] < 30 * 0.34 * 1.1 and r["nonbonded"] is None
    r = run_ring_member(dict(n_bp=120, delta_lk=0, time_ns=0.02, equilibration_ns=0.005, **BARE), tmp_path / "ring")
    assert np.isfinite(r["Wr"]) and abs(r["Wr"]) < 1
    r = run_nicked_member(dict(n_bp=120, time_ns=0.02, equilibration_ns=0.005, **BARE), tmp_path / "nicked")
    assert r is not None


def test_protocol_command_and_simulate_with_no_nonbonded_terms(tmp_path):
    res = CliRunner().invoke(main, ["protocol", "force-extension", "--force", "1", "-s", "24", "--time", "0.01",
                                    "--equilibration", "0.005", "--no-excluded-volume", "--no-electrostatics",
                                    "--workers", "0", "-o", str(tmp_path / "fe")])
    assert res.exit_code == 0, res.output
    assert "relative_extension" in res.output
    res = CliRunner().invoke(main, ["simulate", "20", "--time", "0.005", "--no-excluded-volume",
                                    "--no-electrostatics", "-o", str(tmp_path / "sim")])
    assert res.exit_code == 0, res.output
    run = json.loads((tmp_path / "sim" / "run.json").read_text())
    assert run["spec"]["excluded_volume"] is False and run["spec"]["electrostatics"] is False


def test_checks_take_a_bare_chain():
    from dnarod.physics.theory.supercoil import effective_diameter, ring_constants

    assert effective_diameter(NonbondedSettings(**BARE), 0.34, 300.0) == 0.0
    rc = ring_constants(100, 300.0, 0.15, nonbonded=BARE)
    assert rc["d_eff"] == 0.0 and rc["A"] == pytest.approx(50.0, abs=0.1)
