"""Turns count from the torque-free state at the run's temperature, with the 0 K offset reported beside them.

The offset (:func:`dnarod.physics.loads.torque_free_offset`) is checked against the sampled relaxed twist and, as a
torque, against the exact equilibrium of a pulled, rotation-clamped chain (exact free-chain samples reweighted,
:func:`dnarod.physics.sampling.tweezers_reference`): the clamp held at the offset carries almost no torque, held at
the 0 K twist it carries the torque the issue found."""
import json

import numpy as np
import pytest
from click.testing import CliRunner

from dnarod.core.forcefield import load_forcefield
from dnarod.core.rotations import rotation_about_axis
from dnarod.core.units import kT
from dnarod.physics.loads import intrinsic_turns, torque_free_offset

FF = load_forcefield("dna-default")
Z = np.array([0.0, 0.0, 1.0])


def test_offset_of_the_torque_free_state():
    kbp = FF.model_from_sequence(n_nodes=1000)
    off = torque_free_offset(kbp, 300.0)
    assert off == pytest.approx(-0.42, abs=0.01)  # ~0.42 turns below the 0 K twist for 1 kbp at 300 K
    assert torque_free_offset(kbp, 0.0) == 0.0
    assert torque_free_offset(kbp, 350.0) < off  # more thermal twist fluctuation, lower mean twist
    from dnarod.physics.thermal import relaxed_ribbon_twist

    m = FF.model_from_sequence(n_nodes=300)
    tw, se = relaxed_ribbon_twist(m, 300.0, n_samples=1500, seed=3)
    assert torque_free_offset(m, 300.0) == pytest.approx(tw - intrinsic_turns(m), abs=4 * se)


def test_clamp_at_the_offset_is_torque_free_and_at_0K_is_not():
    from dnarod.physics.sampling import tweezers_reference

    m = FF.model_from_sequence(n_nodes=16)
    off = torque_free_offset(m, 300.0)
    torques = {}
    for name, t in (("T", off), ("0K", 0.0)):
        target = rotation_about_axis(Z, 2 * np.pi * t) @ m.frames[-1]
        r = tweezers_reference(m, 300.0, 2.0, 60000, np.random.default_rng(5), 10 * kT(300.0), target)
        torques[name] = r["clamp_torque_pN_nm"]
    (t_T, _), (t_0, se_0) = torques["T"], torques["0K"]
    assert t_0 > 20 * se_0  # at the 0 K twist the chain is overwound at 300 K (about +1 pN nm for 16 bp)
    assert abs(t_T) < 0.15 * t_0  # at the offset the torque is gone but for a small clamp-geometry residual


def test_member_turns_count_from_the_torque_free_state():
    from dnarod.workflows.protocols.measure import rotation_about_z
    from dnarod.workflows.protocols.tweezers import build_member

    base = FF.model_from_sequence(n_nodes=200)
    off = torque_free_offset(base, 300.0)
    for turns in (0.0, 1.0):
        m = build_member(dict(n_bp=200, force_pN=1.0, turns=turns))
        assert m["turns"] == turns and m["turns_offset_0K"] == pytest.approx(off)
        # the clamp holds the bead's 0 K frame turned by turns + offset
        angle = float(rotation_about_z(m["clamp_target"], base.frames[-1])) / (2 * np.pi)
        # the angle wraps at half a turn
        assert (angle - (turns + off) + 0.5) % 1.0 - 0.5 == pytest.approx(0.0, abs=1e-6)
        assert m["lk_T"] == pytest.approx(intrinsic_turns(base) + off)
    free = build_member(dict(n_bp=200, force_pN=1.0, turns=None))
    assert free["turns_offset_0K"] == 0.0  # no clamp: no turns to count


def test_simulate_turns_from_the_torque_free_state(tmp_path):
    res = CliRunner().invoke(main_cli(), ["simulate", "60", "--time", "0.002", "--pull", "1", "--clamp-first",
                                          "--rotation-clamp", "250", "--no-excluded-volume", "--no-electrostatics",
                                          "-o", str(tmp_path / "r")])
    assert res.exit_code == 0, res.output
    assert "torque-free state" in res.output
    run = json.loads((tmp_path / "r" / "run.json").read_text())
    off = torque_free_offset(FF.model_from_sequence(n_nodes=60), 300.0)
    assert run["spec"]["extra"]["turns_offset_0K"] == pytest.approx(off)
    clamp = [ld for ld in run["spec"]["loads"] if ld["type"] == "RotationClamp"][0]
    assert clamp["offset_turns"] == pytest.approx(off)
    # the engines hold the clamp's target turned by the offset
    from dnarod.physics.loads import RotationClamp, resolve_loads

    model = FF.model_from_sequence(n_nodes=60)
    rc = resolve_loads([RotationClamp(59, 100.0, axis=Z, offset_turns=0.25)], model).rotation_clamps[0]
    assert np.allclose(rc.frame0, rotation_about_axis(Z, np.pi / 2) @ model.frames[-1])


def main_cli():
    from dnarod.cli.main import main

    return main
