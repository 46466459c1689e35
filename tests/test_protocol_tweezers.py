"""Tweezers and ring protocols: observables (Lk = Tw + Wr with a closure, clamp torque, plectoneme detector),
the relaxed start under load, short members against theory, curves and bad input (exit 2)."""
import json

import numpy as np
import pytest
from click.testing import CliRunner

from dnarod.cli.main import main
from dnarod.core.errors import DnarodError
from dnarod.core.forcefield import load_forcefield
from dnarod.physics.nonbonded import NonbondedSettings
from dnarod.workflows.protocols.measure import (CONTACT_PER_DIAMETER, clamp_torque_z, detector_distances,
                                                plectoneme_end_loops, plectoneme_state, rotation_about_z,
                                                twisting_moment)
from dnarod.physics.observables import twist_writhe_open
from dnarod.workflows.protocols.tweezers import check_tweezers, strained_helix
from dnarod.physics.loads import intrinsic_turns
from dnarod.core.rotations import rotation_about_axis
from dnarod.core.strains import chain_from_strains
from dnarod.physics.testsystems import plectoneme_centres
from dnarod.physics.thermal import equilibrium_sample, sample_open_chain_strains
from dnarod.core.units import kT
from dnarod.core.units import PN
from dnarod.physics.theory.supercoil import effective_diameter

FF = load_forcefield("dna-default")


def vertical_ended_chain(n, temperature_factor, rng):
    """A thermal chain whose first and last 20 steps are straight and whose last part is turned back to +z."""
    m = FF.model_from_sequence(n_nodes=n)
    xi = sample_open_chain_strains(m.params, m.ds, kT(300) * temperature_factor, rng)[0]
    xi[:20] = m.params.intrinsic[:20]
    xi[-20:] = m.params.intrinsic[-20:]
    pos, frm = chain_from_strains(xi[:, :3], xi[:, 3:], m.ds)
    k = n - 21
    d = frm[k][:, 2]
    ax = np.cross(d, [0, 0, 1.0])
    R = rotation_about_axis(ax / np.linalg.norm(ax), np.arctan2(np.linalg.norm(ax), d[2]))
    pos[k:] = pos[k] + (pos[k:] - pos[k]) @ R.T
    frm[k:] = R @ frm[k:]
    return pos, frm


def test_open_chain_linking_number_equals_end_rotation_mod_one():
    rng = np.random.default_rng(1)
    for factor in (1.0, 4.0, 10.0):
        pos, frm = vertical_ended_chain(300, factor, rng)
        tw, wr = twist_writhe_open(pos, frm)
        phi = rotation_about_z(frm[-1], frm[0]) / (2 * np.pi)
        assert abs(wr) > 0.05  # a genuinely non-planar chain
        assert abs(((tw + wr - phi) + 0.5) % 1.0 - 0.5) < 1e-6


def test_straight_and_strained_helix_twist():
    m = FF.model_from_sequence(n_nodes=200)
    tw, wr = twist_writhe_open(m.positions, m.frames)
    assert wr == pytest.approx(0.0, abs=1e-12)
    assert tw == pytest.approx(intrinsic_turns(m), abs=1e-9)
    s = strained_helix(m, 2.0, 1.5)
    tw, wr = twist_writhe_open(s.positions, s.frames)
    assert tw + wr - intrinsic_turns(m) == pytest.approx(1.5, abs=1e-9)
    # the linear constitutive law: the twisting moment of the start equals the torque that holds it
    t = twisting_moment(s.positions, s.frames, s.params, s.ds)
    K = m.params.stiffness[0]
    Ci = np.linalg.inv(K)
    th0 = 2 * np.arctan(0.5 * m.ds * m.params.Omega0[0, 2])
    w3 = 2 / m.ds * np.tan(0.5 * (th0 + 2 * np.pi * 1.5 / m.n_steps)) - m.params.Omega0[0, 2]
    tau = (w3 - Ci[2, 5] * 2.0 * PN) / Ci[2, 2]
    assert t == pytest.approx(tau * (1 + (0.5 * m.ds * (m.params.Omega0[0, 2] + w3)) ** 2) / PN, rel=1e-6)
    # stretched: longer than the intrinsic helix by about F/S
    assert s.positions[-1, 2] > m.positions[-1, 2]


def test_clamp_torque_is_k_sin_theta():
    target = np.eye(3)
    k = 100.0
    for ang in (-0.3, 0.05, 0.4):
        frame = rotation_about_axis(np.array([0, 0, 1.0]), ang)
        assert clamp_torque_z(frame, target, k) == pytest.approx(-k * np.sin(ang) / PN, rel=1e-12)


def test_plectoneme_detector():
    ds = 0.34
    straight = np.column_stack([np.zeros(400), np.zeros(400), ds * np.arange(400)])
    assert plectoneme_state(straight, ds)[2] is False
    # an interwound pair: two strands 4 nm apart wound about each other, joined by an end loop
    s = np.arange(200) * ds
    r, pitch = 2.0, 20.0
    up = np.column_stack([r * np.cos(2 * np.pi * s / pitch), r * np.sin(2 * np.pi * s / pitch), s])
    down = np.column_stack([-r * np.cos(2 * np.pi * s / pitch), -r * np.sin(2 * np.pi * s / pitch), s])[::-1]
    plec = np.vstack([up, down])
    frac, length, is_plec = plectoneme_state(plec, ds)
    assert is_plec and frac > 0.8 and length > 100


CALIBRATED = NonbondedSettings()
MANNING = NonbondedSettings(charge="manning", cutoff_debye=5.0)  # the default before the calibration


def _d_eff(nb):
    return effective_diameter(nb, 0.34, 300.0, n_h=80, n_gamma=8, n_offset=2)


def test_detector_distances_follow_the_effective_diameter():
    sep, con = detector_distances(CALIBRATED)
    assert con == pytest.approx(CONTACT_PER_DIAMETER * 5.0, abs=0.05)  # d_eff 5.00 nm at 0.15 M (calibration)
    assert sep == pytest.approx(2 * con)
    # Manning's charge with its 5-Debye-length cutoff reads with the earlier fixed distances
    sep, con = detector_distances(MANNING)
    assert (sep, con) == (25.0, pytest.approx(6.0, abs=0.05))
    # lower salt: wider, so the minimum separation grows with the contact distance; no non-bonded terms: WCA sigma
    sep, con = detector_distances(NonbondedSettings(salt=0.05))
    assert con == pytest.approx(CONTACT_PER_DIAMETER * _d_eff(NonbondedSettings(salt=0.05)), rel=1e-9)
    assert con > 15.0 and sep == pytest.approx(2 * con)
    off = NonbondedSettings(excluded_volume=False, electrostatics=False)
    assert detector_distances(off) == (25.0, pytest.approx(CONTACT_PER_DIAMETER * off.diameter))
    # an explicit contact distance is used as given (the minimum separation then follows it unless given too)
    plec = plectoneme_centres(400, radius=3.5, pitch=4 * np.pi * 3.5)
    assert plectoneme_state(plec, 0.34, 25.0, 6.0) == plectoneme_state(plec, 0.34, contact_distance_nm=6.0)


@pytest.mark.parametrize("separation", [1.4, 1.8, 2.2])
def test_detector_reads_a_superhelix_of_the_calibrated_charge(separation):
    """Ideal plectonemes (two interwound helices and an end loop, 450 nodes) whose strands sit ``separation``
    effective diameters apart, from just above the model's (strand separation peaking at 1.0-1.2 d_eff, its 25 %
    quantile up to 1.7 d_eff; research/plectoneme_detector) to wider: all but the end loop is read with the
    calibrated charge's distances (the default); the earlier fixed 6 nm reads nothing; the same shape scaled to
    Manning's d_eff reads as it did with 6 nm."""
    ds, n = 0.34, 450
    d = _d_eff(CALIBRATED)
    r = 0.5 * separation * d
    plec = plectoneme_centres(n, ds=ds, radius=r, pitch=4 * np.pi * r)  # pitch angle atan(2): strands 2 r apart
    half = n // 2
    gap = np.linalg.norm(plec[:half - 60, None] - plec[None, half + 60:], axis=2).min()
    assert gap == pytest.approx(separation * d, rel=0.02)
    geometric = 1.0 - np.pi * r / (n * ds)  # every node but the end loop's (a semicircle of radius r)
    frac, length, is_plec = plectoneme_state(plec, ds)
    assert is_plec and frac == pytest.approx(geometric, abs=0.03)
    assert plectoneme_state(plec, ds, *detector_distances(CALIBRATED)) == (frac, length, is_plec)
    assert plectoneme_end_loops(plec, ds)[0] == 1
    # the earlier fixed 25 nm / 6 nm: no contact at all, not plectonemic, no end loop (the silent wrong answer)
    assert plectoneme_state(plec, ds, 25.0, 6.0)[:2] == (0.0, 0.0)
    assert plectoneme_end_loops(plec, ds, min_separation_nm=25.0, contact_distance_nm=6.0)[0] == 0
    # Manning's d_eff: the same shape scaled down reads the same with the rule and with the fixed 6 nm
    rm = r * _d_eff(MANNING) / d
    small = plectoneme_centres(n, ds=ds, radius=rm, pitch=4 * np.pi * rm)
    manning = plectoneme_state(small, ds, *detector_distances(MANNING))
    assert manning[0] == pytest.approx(plectoneme_state(small, ds, 25.0, 6.0)[0], abs=1.0 / n)
    assert manning[0] > 1.0 - 25.0 / (n * ds)  # at most the 25 nm about the loop's tip unread


@pytest.mark.parametrize("n_bp", [400, 600])
def test_detector_is_off_for_free_coils_and_stretched_chains(n_bp):
    """Exact equilibrium samples of the free chain (no excluded volume: its random self-approaches are at least
    those of the model): with the calibrated charge's distances (contact 13 nm, separation 26 nm) under 1 % of the
    nodes read as plectoneme on average and under 5 % of the samples are flagged; a chain at a quarter of the
    temperature (stiffer, straighter) reads nothing. With the contact distance of 0.05 M (20 nm) but the minimum
    separation left at 25 nm the free coil would read plectonemes (the reason the separation follows)."""
    m = FF.model_from_sequence(n_nodes=n_bp)
    sep, con = detector_distances(CALIBRATED)
    wide = (25.0, detector_distances(NonbondedSettings(salt=0.05))[1])
    fr, fr_wide = [], []
    for k in range(60):
        P = equilibrium_sample(m, 300.0, seed=7000 + k).positions
        fr.append(plectoneme_state(P, m.ds, sep, con)[0])
        fr_wide.append(plectoneme_state(P, m.ds, *wide)[0])
    fr, fr_wide = np.array(fr), np.array(fr_wide)
    assert fr.mean() < 0.01 and (fr >= 0.05).mean() < 0.05
    assert fr_wide.mean() > 3 * fr.mean() and fr_wide.mean() > 0.01
    cold = equilibrium_sample(m, 75.0, seed=11).positions
    assert plectoneme_state(cold, m.ds, sep, con)[:2] == (0.0, 0.0)


def test_bad_tweezers_input_is_refused():
    with pytest.raises(DnarodError, match="rotation clamp"):
        check_tweezers(1.0, 2.0, rotation_clamp=False)
    with pytest.raises(DnarodError, match="no pulling force"):
        check_tweezers(0.0, None, torque_pN_nm=10.0)
    with pytest.raises(DnarodError, match="overstretches"):
        check_tweezers(80.0)
    with pytest.raises(DnarodError, match="sigma"):
        check_tweezers(1.0, 10.0, lk0=57.0)


@pytest.mark.parametrize("args, words", [
    (["force-extension", "--force", "1", "--turns", "2"], "rotation clamp"),
    (["hat", "--turns", "1", "--force", "0"], "pulling force"),
    (["hat", "--turns", "30"], "sigma"),
    (["torque-turns", "--turns", "1", "--force", "70"], "overstretches"),
    (["rings", "--delta-lk", "0.5"], "integer"),
    (["rings", "--delta-lk", "-20"], "sigma"),
    (["hat", "--turns", "one"], "comma-separated numbers"),
    # the turn-sweep starts left the product (research/turn_sweeps): their options are unknown now
    (["hat", "--turns", "1", "--settle", "5"], "No such option '--settle'"),
    (["hat", "--turns", "1", "--start", "sweep"], "'sweep' is not one of 'static', 'exchange'"),
    (["force-extension", "--force", "1", "--start", "sweep"], "No such option"),
])
def test_protocol_cli_misuse_exits_2(tmp_path, args, words):
    res = CliRunner().invoke(main, ["protocol", *args, "-o", str(tmp_path / "out")])
    assert res.exit_code == 2, res.output
    assert words in res.output and "Traceback" not in res.output
    assert not (tmp_path / "out").exists()  # nothing written


def test_torque_turns_curve_short_chain(tmp_path):
    """100 bp at 3 pN, +-0.5 turns: the slope gives C_eff near Moroz-Nelson; Lk tracks the clamp; files written."""
    from dnarod.workflows.protocols import torque_turns
    from dnarod.physics.theory.torsion import bare_twist_persistence, moroz_nelson

    c = torque_turns([-0.5, 0.5], tmp_path / "tt", force_pN=3.0, source="100", workers=0,
                     base=dict(time_ns=0.3, equilibration_ns=0.1, seed=3))
    assert c.files["csv"].exists() and c.files["png"].stat().st_size > 1000
    lo, hi = c.rows
    for r, t in ((lo, -0.5), (hi, 0.5)):
        # the clamp lags by torque / k (a few hundredths of a turn); Lk = Tw + Wr follows the end rotation
        assert r["delta_lk"] == pytest.approx(r["end_turns"], abs=0.01)
        assert abs(r["end_turns"] - t) < 0.05
        assert r["twist_torque_pN_nm_tau_ps"] is not None and r["n_samples"] >= 10
        assert r["lk_slips"] == 0  # the surface and bead walls keep the linking number topological
    m = FF.model_from_sequence(n_nodes=100)
    L = m.ds * m.n_steps
    kt_pn = kT(300) / PN
    C = (L * (hi["twist_torque_pN_nm"] - lo["twist_torque_pN_nm"])
         / (kt_pn * 2 * np.pi * (hi["delta_lk"] - lo["delta_lk"])))
    theory = moroz_nelson(bare_twist_persistence(m, 300.0), 50.0, 3.0, kt_pn)
    assert C == pytest.approx(theory, rel=0.12)
    rows = (tmp_path / "tt" / "curve.csv").read_text().splitlines()
    assert len(rows) == 3 and "twist_torque_pN_nm" in rows[0] and "twist_torque_pN_nm_raw" in rows[0]
    # the curve's torque is on the model's zero at T: the raw twisting moment less its free-chain reading, and its
    # linking difference is counted from the relaxed twist at T (both computed independently here): the members count
    # their turns from it (delta_lk equals delta_lk_thermal), the exact offset agreeing with the sampled relaxed twist
    from dnarod.physics.loads import intrinsic_turns, torque_free_offset
    from dnarod.physics.thermal import relaxed_ribbon_twist
    from dnarod.workflows.protocols.measure import twisting_moment_offset

    off, _ = twisting_moment_offset(m, 300.0)
    lk_T = intrinsic_turns(m) + torque_free_offset(m, 300.0)
    sampled, se = relaxed_ribbon_twist(m, 300.0)
    assert lk_T == pytest.approx(sampled, abs=4 * se)
    for r in (lo, hi):
        assert r["twist_torque_pN_nm_raw"] - r["twist_torque_pN_nm"] == pytest.approx(off, abs=1e-9)
        assert r["delta_lk_thermal"] == pytest.approx(r["Lk"] - lk_T, abs=1e-9)
        assert r["delta_lk"] == pytest.approx(r["delta_lk_thermal"], abs=1e-9)
        assert r["turns_offset_0K"] == pytest.approx(torque_free_offset(m, 300.0))
    # so the torque vanishes where the linking difference does (the old T = 0 pair read ~+2.4 pN nm there)
    w = -lo["delta_lk_thermal"] / (hi["delta_lk_thermal"] - lo["delta_lk_thermal"])
    tau0 = (1 - w) * lo["twist_torque_pN_nm"] + w * hi["twist_torque_pN_nm"]
    se0 = float(np.hypot((1 - w) * lo["twist_torque_pN_nm_err"], w * hi["twist_torque_pN_nm_err"]))
    assert abs(tau0) <= 3 * se0, (tau0, se0)
    # a second call reuses the finished members (same settings)
    again = torque_turns([-0.5, 0.5], tmp_path / "tt", force_pN=3.0, source="100", workers=0,
                         base=dict(time_ns=0.3, equilibration_ns=0.1, seed=3))
    assert again.rows[0]["wall_s"] == lo["wall_s"]


def test_ring_member_conserves_linking_number(tmp_path):
    from dnarod.workflows.protocols.rings import run_ring_member

    r = run_ring_member(dict(n_bp=150, delta_lk=-1, time_ns=0.1, equilibration_ns=0.05, seed=2), tmp_path / "ring")
    assert r["lk_integer"] is not None
    assert r["delta_lk_measured"] == pytest.approx(-1.0, abs=1e-6)
    assert r["Tw"] + r["Wr"] == pytest.approx(r["Lk"], abs=1e-6)
    res = json.loads((tmp_path / "ring" / "protocol_result.json").read_text())
    assert res["result"]["n_samples"] >= 4
    # the detector ran with the member's own model's distances (the default terms: the calibrated charge at 0.15 M)
    rule = detector_distances(CALIBRATED)
    assert (r["plectoneme_min_separation_nm"], r["plectoneme_contact_nm"]) == pytest.approx(rule)


def test_torsion_check_passes_and_fails_with_a_wrong_twist_stiffness(tmp_path):
    from dnarod.validate.torsion import check_torsion

    opts = dict(n_bp=100, slope_ns=0.3, fluct_ns=4.0, plots=False, member_root=tmp_path / "members")
    good = check_torsion(tmp_path, quick=True, **opts)
    assert good["passed"], good
    bad = check_torsion(tmp_path, quick=True, c_override=60.0, **opts)  # reuses the members
    assert not bad["passed"]


@pytest.mark.slow
@pytest.mark.parametrize("kind, axes", [("magnetic_tweezers", {"turns": [-0.3, 0.3]}),
                                        ("rings", {"delta_lk": [-1, 0]})])
def test_protocols_through_the_ensemble_layer(tmp_path, kind, axes):
    """The same members through dnarod.workflows.ensemble (dask LocalCluster, one worker)."""
    from dnarod.workflows.protocols import run_protocol

    base = dict(source="100" if kind != "rings" else "150", time_ns=0.1, equilibration_ns=0.05, seed=4)
    if kind != "rings":
        base["force_pN"] = 2.0
    c = run_protocol(kind, axes, base, tmp_path / kind, workers=1, progress=False)
    assert len(c.rows) == 2 and c.files["png"].exists()
    assert (tmp_path / kind / "ensemble" / "results.csv").exists()


def test_bracketing_starts_keep_the_linking_number(tmp_path):
    """Starts from another side of the equilibrium keep the linking number: a tweezers member started from a
    given pose at its own turns (another member's final pose) has the straight start's Lk, and the plectonemes
    check's writhed ring start (bending softened threefold for a while, then the model) has the ring's Lk."""
    from dnarod.core.forcefield import load_forcefield
    from dnarod.core.units import kT
    from dnarod.physics.thermal import persistence_length
    from dnarod.validate.plectonemes import bend_softened_model, writhed_start
    from dnarod.workflows.protocols.poses import FINAL_POSE, START_POSE, load_pose
    from dnarod.workflows.protocols.rings import run_ring_member
    from dnarod.workflows.protocols.tweezers import run_member

    base = dict(n_bp=100, force_pN=1.0, turns=0.8, time_ns=0.02, equilibration_ns=0.01, seed=3)
    a = run_member(base, tmp_path / "straight")
    pose = load_pose(tmp_path / "straight" / FINAL_POSE)
    b = run_member(dict(base, previous_turns=0.8, seed=4), tmp_path / "posed", start_pose=pose)
    assert a["lk_slips"] == 0 and b["lk_slips"] == 0
    assert b["Lk"] == pytest.approx(a["Lk"], abs=0.05) and b["previous_turns"] == 0.8 and "given pose" in b["start"]
    np.testing.assert_array_equal(load_pose(tmp_path / "posed" / START_POSE)[0], pose[0])
    with pytest.raises(DnarodError, match="previous_turns"):
        run_member(base, tmp_path / "no_turns", start_pose=pose)
    rule = detector_distances(CALIBRATED)  # the detector's distances of the member's terms, recorded in the row
    assert (a["plectoneme_min_separation_nm"], a["plectoneme_contact_nm"]) == pytest.approx(rule)
    ring = load_forcefield("dna-default").ring(n_nodes=200)
    soft = bend_softened_model(ring, 3.0)
    lp = persistence_length(ring.params, ring.ds, kT(300.0))
    assert persistence_length(soft.params, soft.ds, kT(300.0)) == pytest.approx(lp / 3.0, rel=0.05)
    rs = dict(n_bp=200, delta_lk=-1, time_ns=0.02, equilibration_ns=0.01)
    start = writhed_start(rs, 3.0, 0.02, tmp_path / "ring")
    r = run_ring_member(rs, tmp_path / "ring", start_pose=start)
    assert r["lk_integer"] == 18 and r["relaxed_twist_thermal"] < r["intrinsic_turns"] - 0.05
    # the kept start pose is what a rerun starts from: the finished member is reused, nothing is prepared again
    np.testing.assert_array_equal(writhed_start(rs, 3.0, 0.02, tmp_path / "ring")[0], start[0])
    assert run_ring_member(rs, tmp_path / "ring", start_pose=start)["wall_s"] == r["wall_s"]
    with pytest.raises(DnarodError, match="linking number"):
        run_ring_member(dict(rs, delta_lk=0), tmp_path / "ring0", start_pose=start)


def test_tweezers_member_resumes_from_its_checkpoint(tmp_path):
    """A member interrupted mid-production resumes from its checkpoint: the samples before the interruption
    are kept, the run continues from the saved state, and the finished member matches an uninterrupted one."""
    from dnarod.workflows.protocols import tweezers as tw

    settings = dict(n_bp=40, force_pN=2.0, turns=0.3, time_ns=0.05, equilibration_ns=0.02, sample_ps=2.0, seed=3,
                    platform="Reference")
    ref, _ = tw.sample_member(tw.build_member(settings))

    class Stop(Exception):
        pass

    def stop_at(i, n):
        if i == 12:
            raise Stop

    ck = tmp_path / "ck.npz"
    with pytest.raises(Stop):
        tw.sample_member(tw.build_member(settings), stop_at, checkpoint=ck, checkpoint_wall_s=1e-9)
    assert ck.exists()
    # one checkpoint format: the engine's own (as for `dnarod simulate`), the samples in its metadata
    with np.load(ck) as z:
        meta = json.loads(str(z["meta"]))
    assert meta["format"] == "dnarod-openmm-checkpoint" and len(meta["extra"]["reporters"]["samples"]["rows"]
                                                                  ["extension_nm"]) == 11
    seen = []
    got, cost = tw.sample_member(tw.build_member(settings), lambda i, n: seen.append(i), checkpoint=ck)
    assert seen[0] == 12  # the 11 samples saved before the interruption were not redone
    assert len(got["time_ps"]) == len(ref["time_ps"]) == 25
    np.testing.assert_allclose(got["time_ps"], ref["time_ps"])
    np.testing.assert_allclose(got["extension_nm"][:11], ref["extension_nm"][:11], rtol=1e-12)
    # same state and random stream after the restart: the continued samples agree with the uninterrupted run
    np.testing.assert_allclose(got["extension_nm"], ref["extension_nm"], rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(got["end_turns"], ref["end_turns"], rtol=1e-6, atol=1e-6)
    # a checkpoint of other settings is refused in one line
    other = dict(settings, seed=4)
    with pytest.raises(DnarodError, match="other settings"):
        tw.sample_member(tw.build_member(other), checkpoint=ck)


def test_add_turns_adds_twist_only():
    """Turning a pose by dt adds dt to the twist (so to Lk), keeps positions, writhe and node 0's frame, and
    turns the last node by 2 pi dt about its own d3."""
    from dnarod.workflows.protocols.poses import add_turns

    m = strained_helix(FF.model_from_sequence(n_nodes=60), 1.0, 0.3)
    rng = np.random.default_rng(5)
    pos = m.positions + rng.normal(0.0, 0.05, m.positions.shape)
    tw0, wr0 = twist_writhe_open(pos, m.frames)
    P, F = add_turns(pos, m.frames, 0.7)
    tw1, wr1 = twist_writhe_open(P, F)
    np.testing.assert_array_equal(P, pos)
    assert wr1 == wr0 and tw1 - tw0 == pytest.approx(0.7, abs=1e-9)
    np.testing.assert_allclose(F[0], m.frames[0], atol=1e-15)
    np.testing.assert_allclose(np.einsum("nij,nik->njk", F, F), np.broadcast_to(np.eye(3), F.shape), atol=1e-12)
    np.testing.assert_allclose(F[-1], m.frames[-1] @ rotation_about_axis(np.array([0.0, 0.0, 1.0]), 2 * np.pi * 0.7),
                               atol=1e-12)


def test_member_seed_is_distinct_and_reproducible():
    """The same base seed and key give the same seed; another key, base seed or direction another one; all in
    [1, 2^31); static members of a curve get distinct seeds too (each one from its force and turns)."""
    from dnarod.workflows.protocols.ensemble_hooks import MAGNETIC_TWEEZERS, member_seed

    a = member_seed(1, "magnetic_tweezers", 1.0, 0.8)
    assert a == member_seed(1, "magnetic_tweezers", 1.0, 0.8) == member_seed(1, "magnetic_tweezers", 1, 0.8)
    others = [member_seed(2, "magnetic_tweezers", 1.0, 0.8), member_seed(1, "torque_turns", 1.0, 0.8),
              member_seed(1, "magnetic_tweezers", 0.5, 0.8), member_seed(1, "magnetic_tweezers", 1.0, -0.8),
              member_seed(a, "sweep"), member_seed(a, "sweep-in")]
    assert len({a, *others}) == 7 and all(1 <= x < 2**31 for x in (a, *others))
    turns = [-4.8, -4, -3.2, -2.4, -1.6, -0.8, 0, 0.8, 1.6, 2.4, 3.2, 4]
    seeds = [MAGNETIC_TWEEZERS.member_settings(dict(source="100", force_pN=1.0, turns=t, seed=1))["seed"]
             for t in turns]
    assert len(set(seeds)) == len(turns)


def test_member_keys_carry_the_non_bonded_terms(tmp_path):
    """A member folder recorded with other non-bonded terms (charge model, cutoff) is not taken for a member with
    the defaults: the terms are member settings, so they are part of each protocol's cache key."""
    import json

    from dnarod.core.errors import DnarodError
    from dnarod.core.io import jsonable
    from dnarod.physics.nonbonded import DEFAULT_CHARGE, DEFAULT_CUTOFF_DEBYE, member_nonbonded
    from dnarod.workflows.protocols import nicked, rings, tweezers

    for mod in (rings, nicked, tweezers):
        s = mod._settings({})
        assert (s["charge"], s["cutoff_debye"]) == (DEFAULT_CHARGE, DEFAULT_CUTOFF_DEBYE), mod.__name__
        nb = member_nonbonded(s)
        assert (nb.charge, nb.cutoff_debye, nb.salt) == (DEFAULT_CHARGE, DEFAULT_CUTOFF_DEBYE, 0.15)
    old = rings._settings({"charge": "manning", "cutoff_debye": 5.0})
    (tmp_path / "protocol_result.json").write_text(json.dumps({"settings": jsonable(old), "result": {"x": 1}}))
    assert rings.cached_member(tmp_path, jsonable(old))[0] == {"x": 1}
    assert rings.cached_member(tmp_path, jsonable(rings._settings({})))[0] is None
    for bad in (dict(charge="bogus"), dict(charge=-1.0), dict(cutoff_debye=0.0)):
        with pytest.raises(DnarodError):
            member_nonbonded(rings._settings(bad))


def test_protocol_members_take_the_automatic_platform_unless_asked_and_both_host_platforms_agree(monkeypatch):
    """Protocol members (tweezers, rings) name the platform they run on: the one asked for, else the automatic
    choice with the worker's one thread, which without a GPU is the Reference platform (the CPU platform hands
    every step to a worker thread even with one thread; ``benchmarks/bench_exchange_platform.py``). The CPU
    platform stays available with its thread count, and the two give the same System: the same energy and forces
    on a tweezers member's twisted start pose (forces to 1e-4 of their scale)."""
    import openmm

    from dnarod.engines.openmm.platforms import choose_platform
    from dnarod.workflows.protocols import tweezers as tw
    from dnarod.workflows.protocols.ensemble_hooks import MAGNETIC_TWEEZERS, RINGS

    monkeypatch.setenv("OPENMM_CPU_THREADS", "1")
    auto = choose_platform(None, threads=1)[0].getName()
    assert auto != "CPU"  # one thread never picks the CPU platform's worker thread
    proto = MAGNETIC_TWEEZERS
    base = dict(source="300", force_pN=1.0, turns=2.0, time_ns=0.01)
    for p in (proto, RINGS):
        got = p.member_settings(base)
        assert (got["platform"], got["threads"]) == (auto, None)
        cpu = p.member_settings({**base, "platform": "CPU"})
        assert (cpu["platform"], cpu["threads"]) == ("CPU", 1)
    # a member run directly (validate checks, run_member) resolves the same way, so both share one cache key
    direct = tw.build_member(dict(n_bp=300, force_pN=1.0, turns=2.0, time_ns=0.01))["settings"]
    assert (direct["platform"], direct["threads"]) == (auto, None)
    # the automatic choice follows the member's elastic path (the portable path prefers the CPU platform)
    portable = tw.build_member(dict(n_bp=300, force_pN=1.0, turns=2.0, time_ns=0.01, elastic="portable"))["settings"]
    assert portable["platform"] == choose_platform(None, threads=1, elastic="portable")[0].getName()
    for bad in ("two", "0", "-1"):  # OpenMM's own variable, misspelt: one line, not a traceback
        monkeypatch.setenv("OPENMM_CPU_THREADS", bad)
        with pytest.raises(DnarodError, match="OPENMM_CPU_THREADS"):
            proto.member_settings(base)
    monkeypatch.setenv("OPENMM_CPU_THREADS", "2")
    if auto == "Reference":  # no GPU: two threads ask for the multithreaded CPU platform
        assert (proto.member_settings(base)["platform"], proto.member_settings(base)["threads"]) == ("CPU", 2)

    m = tw.build_member(dict(n_bp=300, force_pN=1.0, turns=2.0, time_ns=0.01, seed=4, platform="Reference"))
    ref = tw._member_simulation(m, m["model"])
    assert ref.context.getPlatform().getName() == "Reference"
    m_cpu = {**m, "settings": {**m["settings"], "platform": "CPU", "threads": 1}}
    other = tw._member_simulation(m_cpu, m["model"])
    assert other.context.getPlatform().getName() == "CPU"
    unit_f = openmm.unit.kilojoule_per_mole / openmm.unit.nanometer
    states = [s.context.getState(getEnergy=True, getForces=True) for s in (ref, other)]
    e = [st.getPotentialEnergy().value_in_unit(openmm.unit.kilojoule_per_mole) for st in states]
    f = [np.asarray(st.getForces(asNumpy=True).value_in_unit(unit_f)) for st in states]
    assert abs(e[0]) > 1.0 and e[0] == pytest.approx(e[1], rel=1e-5, abs=1e-3)
    assert np.max(np.abs(f[0] - f[1])) < 1e-4 * np.max(np.abs(f[0]))


def test_ring_member_interrupted_and_resumed_gives_the_uninterrupted_samples(tmp_path, monkeypatch):
    """A ring member runs on the run layer: interrupted mid-production, it resumes from the engine's checkpoint
    (with the samples so far) and writes the samples an uninterrupted member writes; the checkpoint is removed."""
    import dnarod.run.sampling as sampling
    from dnarod.workflows.protocols.rings import run_ring_member

    settings = dict(n_bp=120, delta_lk=-1, time_ns=0.02, equilibration_ns=0.01, sample_ps=1.0, seed=5,
                    platform="Reference")
    run_ring_member(settings, tmp_path / "ref")

    class Stop(Exception):
        pass

    def stop_at(i, n):
        if i == 7:
            raise Stop

    monkeypatch.setattr(sampling, "CHECKPOINT_WALL_S", 1e-9)  # a checkpoint at every sample
    with pytest.raises(Stop):
        run_ring_member(settings, tmp_path / "cut", progress=stop_at)
    assert (tmp_path / "cut" / "member_checkpoint.npz").exists()
    seen = []
    run_ring_member(settings, tmp_path / "cut", progress=lambda i, n: seen.append(i))
    assert seen[0] == 7  # the samples before the interruption were not redone
    ref = np.loadtxt(tmp_path / "ref" / "samples.csv", delimiter=",", skiprows=1)
    got = np.loadtxt(tmp_path / "cut" / "samples.csv", delimiter=",", skiprows=1)
    assert got.shape == ref.shape and got.shape[0] >= 20
    np.testing.assert_allclose(got, ref, rtol=1e-6, atol=1e-9)
    assert not (tmp_path / "cut" / "member_checkpoint.npz").exists()
