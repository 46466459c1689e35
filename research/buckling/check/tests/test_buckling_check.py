"""The buckling check (research/buckling/check; until 2026-12-07 check ``buckling`` of ``dnarod validate``): its
statistics (blocked errors, Chodera's equilibration start, the ring pair's premise), its member plan, its theory
helpers, and its decisions on recorded members (``data/``: the protocol_result.json and samples.csv that the
members wrote when the check was run; the check reuses a member whose settings match, so these tests decide in
seconds; the slow test reruns the simulations)."""
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).parent / "data"


def test_two_phase_with_a_measured_equation_of_state():
    """A linear plectoneme equation of state (one point, tau = kT P Omega) gives Marko's closed form exactly; a
    phase stiffer at low linking density (a second point with larger P below) raises the plateau; points whose
    torque falls as the density rises are refused."""
    from dnarod.core.errors import DnarodError
    from buckling_theory import two_phase_from_plectoneme_eos
    from dnarod.physics.theory.supercoil import marko_two_phase

    kt, A, Cs, P = 4.1419, 50.0, 84.24, 19.77
    m = marko_two_phase(A, Cs, P, 1.0, kt, 203.7)
    e = two_phase_from_plectoneme_eos([0.135], [kt * P * 0.135], A, Cs, 1.0, kt, 203.7)
    assert e["torque_pN_nm"] == pytest.approx(m["torque_pN_nm"], rel=1e-9)
    assert e["omega_p"] == pytest.approx(m["omega_p"], rel=1e-9) and e["extrapolated"]
    stiff = two_phase_from_plectoneme_eos([0.03, 0.135], [kt * 40.0 * 0.03, kt * P * 0.135], A, Cs, 1.0, kt, 203.7)
    assert stiff["torque_pN_nm"] > m["torque_pN_nm"] + 1.0
    with pytest.raises(DnarodError, match="increase together"):
        two_phase_from_plectoneme_eos([0.03, 0.135], [6.0, 5.0], A, Cs, 1.0, kt, 203.7)


def test_ring_pair_bulk_torque_is_kT_P_b_Omega():
    """The pair's bulk torque equals kT P_b Omega with P_b from plectoneme_P_from_ring_pair (the same rings)."""
    from buckling_theory import ring_pair_bulk_torque
    from dnarod.physics.theory.supercoil import plectoneme_P_from_ring_pair

    kt, C = 4.1419, 98.25
    om, tau, se = ring_pair_bulk_torque(-1.924, -2.923, 136.0, -4.267, -5.856, 272.0, C, kt, 0.013, 0.017)
    P, P_se = plectoneme_P_from_ring_pair(-1.924, -2.923, -4.267, -5.856, C, 0.013, 0.017)
    assert om == pytest.approx(2 * np.pi * 2.933 / 136.0)
    assert tau == pytest.approx(kt * P * om, rel=1e-9) and se == pytest.approx(kt * P_se * om, rel=1e-9)


def test_loop_corrected_ring_pair_recovers_the_bulk_P():
    """Rings whose writhe is a bulk share of ΔLk less a fixed deficit per end loop: with different loop counts
    the pair formula is biased, the loop-counted one is exact, and with equal counts the two coincide."""
    from buckling_theory import plectoneme_P_from_rings_with_loops
    from dnarod.physics.theory.supercoil import plectoneme_P_from_ring_pair

    C, P_b, mu = 98.3, 18.0, 0.3
    f = 1 - P_b / C
    rings = [(dlk, n, f * dlk + n * mu) for dlk, n in ((-4.9, 1.96), (-9.8, 2.64))]  # ΔLk < 0: Wr less negative
    (d1, n1, w1), (d2, n2, w2) = rings
    P, err, m = plectoneme_P_from_rings_with_loops(w1, d1, n1, w2, d2, n2, C, 0.02, 0.02)
    assert P == pytest.approx(P_b, rel=1e-9) and m == pytest.approx(mu, rel=1e-9) and 0 < err < 2.0
    assert plectoneme_P_from_ring_pair(w1, d1, w2, d2, C)[0] > P_b + 3.0  # branching biases the pair upwards
    w2_same = f * d2 + n1 * mu
    assert plectoneme_P_from_rings_with_loops(w1, d1, n1, w2_same, d2, n1, C)[0] == pytest.approx(
        plectoneme_P_from_ring_pair(w1, d1, w2_same, d2, C)[0], rel=1e-9)


def test_block_standard_error_sees_a_slow_mode():
    """Fast noise plus a slow small-amplitude mode: the blocked error finds the slow part that the
    autocorrelation-time window misses."""
    from dnarod.analysis.polymer import integrated_autocorrelation_time
    from buckling_check import block_standard_error

    rng = np.random.default_rng(1)
    n, tau_slow = 4000, 60.0
    a = math.exp(-1 / tau_slow)
    slow = np.zeros(n)
    for i in range(1, n):
        slow[i] = a * slow[i - 1] + math.sqrt(1 - a * a) * rng.normal()
    x = 3.0 * rng.normal(size=n) + 0.5 * slow
    exact = math.sqrt((9.0 + 0.25 * (1 + a) / (1 - a)) / n)  # large-n SE of the mean
    blocked = block_standard_error(x)
    tau = integrated_autocorrelation_time(x)
    naive = x.std(ddof=1) * math.sqrt(2 * tau / n)
    assert blocked == pytest.approx(exact, rel=0.3)
    assert naive < 0.8 * exact


def test_equilibration_start_cuts_a_transient_and_keeps_a_stationary_series():
    """Chodera's rule on AR(1) noise (correlation time 10 samples), five seeds: a decaying start (5 sigma, 1/e over
    100 samples) is cut past 1.5 decay times (down to 1.1 sigma), a stationary series keeps at least 3/4 of its
    samples (the rule may drop a noisy stretch, never the bulk)."""
    from buckling_check import equilibration_start

    n, a = 4000, np.exp(-1.0 / 10.0)
    t = np.arange(n)
    for seed in range(5):
        e = np.random.default_rng(seed).normal(size=n) * np.sqrt(1 - a * a)
        x = np.empty(n)
        x[0] = e[0]
        for i in range(1, n):
            x[i] = a * x[i - 1] + e[i]
        assert 150 <= equilibration_start(x + 5.0 * np.exp(-t / 100.0)) <= n // 2
        assert equilibration_start(x) <= n // 4


def _ring_dir(path, wr, loops=None):
    path.mkdir()
    cols = {"time_ps": np.arange(len(wr)) * 200.0, "Wr": wr}
    if loops is not None:
        cols["end_loops"] = loops
    lines = [",".join(cols)] + [",".join(f"{cols[c][i]:.10g}" for c in cols) for i in range(len(wr))]
    (path / "samples.csv").write_text("\n".join(lines) + "\n")
    return path


def test_ring_pair_premise_fails_on_a_branched_or_drifting_ring(tmp_path):
    from buckling_check import ring_pair_premise

    rng = np.random.default_rng(3)
    wr = lambda m: m + 0.1 * rng.normal(size=200)  # noqa: E731
    short = _ring_dir(tmp_path / "short", wr(-3.0), np.full(200, 2))
    good = ring_pair_premise(short, _ring_dir(tmp_path / "long", wr(-7.0), np.full(200, 2)))
    assert good["passed"] and good["end_loops"] == [2.0, 2.0] and good["end_loop_histograms"][1] == [0, 0, 200]
    # the long ring branches a quarter of the time: more end loops than the pair formula cancels
    branched = ring_pair_premise(short, _ring_dir(tmp_path / "br", wr(-7.0), np.r_[np.full(150, 2), np.full(50, 3)]))
    assert not branched["passed"] and branched["loop_difference"] == pytest.approx(0.25)
    # the long ring's writhe still growing: not settled
    drifting = ring_pair_premise(short, _ring_dir(tmp_path / "dr", wr(-7.0) - np.linspace(0, 1, 200), np.full(200, 2)))
    assert not drifting["settled"] and not drifting["passed"]
    # members recorded without the end-loop count: the premise is not shown, so it does not pass
    old = ring_pair_premise(short, _ring_dir(tmp_path / "old", wr(-7.0)))
    assert not old["passed"] and "not recorded" in old["reason"]


def _recorded(tmp_path, name):
    dst = tmp_path / name
    shutil.copytree(DATA / name, dst)
    return dst


def test_members_run_in_advance_from_the_plan_are_reused_by_the_check(tmp_path, monkeypatch):
    """member_plan gives exactly the members check_buckling runs (the check itself is shown reusing them in
    test_supercoiling): the recorded members' folders and settings are found, nothing is simulated (the
    samplers are disabled here)."""
    import shutil

    import dnarod.workflows.protocols.rings as rings
    import dnarod.workflows.protocols.tweezers as tweezers
    from buckling_check import member_plan, run_planned

    root = tmp_path / "members"
    shutil.copytree(DATA / "buckling_600bp", root)
    opts = dict(time_ns=6.0, pre_turns=1.141, post_turns=(4.2786, 5.5907), ring_n_bp=600, ring_delta_lk=-3, ring_time_ns=10.0,
                bracket=False, ring_pair=False, nonbonded=dict(charge="manning", cutoff_debye=5.0),
                platform="CPU")  # the recorded members ran on the CPU platform with one thread
    plan = member_plan(**opts)
    assert sorted(e["folder"] for e in plan) == sorted(p.name for p in root.iterdir() if p.is_dir())

    def refuse(*a, **k):
        raise AssertionError("a planned member was simulated instead of reused")

    monkeypatch.setattr(tweezers, "sample_member", refuse)
    monkeypatch.setattr(rings, "sample_ring", refuse)
    rows = [run_planned(e, root) for e in plan]
    assert [r["seed"] for r in rows] == [e["settings"]["seed"] for e in plan]
    # another production time is another member (a rerun, refused here)
    with pytest.raises(AssertionError, match="simulated instead of reused"):
        run_planned(member_plan(**dict(opts, time_ns=7.0))[-1], root)
    # ... and so is another platform: the automatic choice (Reference without a GPU) is not the recorded CPU run
    with pytest.raises(AssertionError, match="simulated instead of reused"):
        run_planned(member_plan(**dict(opts, platform=None))[-1], root)


def test_buckling_check_against_marko_with_recorded_members(tmp_path, monkeypatch):
    """600 bp at 1 pN, recorded members of 6 ns (Manning's charge): the Marko comparison passes with the model's C
    and fails with C halved; the members are reused, not rerun.

    These members decide the comparison's logic only: analysed from their equilibration start (Chodera's rule on
    the extension) the 4.28-turn member still drifts (6 ns is far too short), so the check as a whole fails on
    them; the calibrated-charge members below pass it.
    """
    from buckling_check import check_buckling

    import dnarod.workflows.protocols.rings as rings
    import dnarod.workflows.protocols.tweezers as tweezers

    def refuse(*a, **k):
        raise AssertionError("a recorded member was simulated again instead of reused")

    monkeypatch.setattr(tweezers, "sample_member", refuse)  # the check must reuse every recorded member
    monkeypatch.setattr(rings, "sample_ring", refuse)
    root = _recorded(tmp_path, "buckling_600bp")
    opts = dict(plots=False, member_root=root, time_ns=6.0, pre_turns=1.141, post_turns=(4.2786, 5.5907),
                ring_n_bp=600, ring_delta_lk=-3, ring_time_ns=10.0, bracket=False, ring_pair=False,
                # the recorded members' settings (one ring: logic only; run on the CPU platform, one thread)
                nonbonded=dict(charge="manning", cutoff_debye=5.0), platform="CPU")
    good = check_buckling(tmp_path, **opts)
    assert good["marko"]["passed"] and not good["drift"]["settled"] and not good["passed"], good
    bad = check_buckling(tmp_path, **opts,
                         c_override=0.5 * good["marko"]["twist_persistence_nm"])
    assert not bad["marko"]["passed"] and not bad["passed"]


def test_buckling_full_check_passes_on_recorded_calibrated_members(tmp_path, monkeypatch):
    """The full form with the calibrated charge and the check's defaults (600 bp at 1 pN, 300-ns straight and
    "above" twins at 2.57 and 3.59 turns, a 400/800-bp ring pair; research/buckling/r7): recorded members, reused
    (nothing is simulated). The check passes; it fails with C halved, and the plain two-phase plateau (without the
    single-plectoneme position entropy) misses by 1.36 pN nm against a tolerance of 1.09."""
    import dnarod.workflows.protocols.rings as rings
    import dnarod.workflows.protocols.tweezers as tweezers
    from buckling_check import check_buckling

    def refuse(*a, **k):
        raise AssertionError("a recorded member was simulated again instead of reused")

    monkeypatch.setattr(tweezers, "sample_member", refuse)
    monkeypatch.setattr(rings, "sample_ring", refuse)
    root = _recorded(tmp_path, "buckling_calibrated")
    opts = dict(plots=False, member_root=root, ring_seed=7, platform="CPU")  # recorded on the CPU platform
    good = check_buckling(tmp_path, **opts)
    assert good["passed"] and good["drift"]["settled"] and good["ring_pair_premise"]["passed"], good["gates"]
    mk = good["marko"]
    assert mk["P_nm"] == pytest.approx(19.77, abs=0.01) and mk["torque_pN_nm"] == pytest.approx(12.53, abs=0.01)
    assert good["plateau"]["mean_torque_pN_nm"] == pytest.approx(13.88, abs=0.01)
    assert not mk["plain_passed"] and abs(mk["residual_pN_nm"]) < mk["tolerance_pN_nm"]
    assert [b["agree"] for b in good["brackets"]] == [True, True]
    bad = check_buckling(tmp_path, c_override=0.5 * mk["twist_persistence_nm"], **opts)
    assert not bad["marko"]["passed"] and not bad["passed"]
    assert not bad["pre_buckling"]["passed"]  # the quick form's gate: the pre-buckling law fails with C halved too


@pytest.mark.slow  # research check, several seconds of MD: run with -m slow
def test_buckling_check_fails_without_plectonemes(tmp_path):
    """Fast: unbuckled 'post-buckling' members (too few turns) must fail the plateau check."""
    from buckling_check import check_buckling

    r = check_buckling(tmp_path, n_bp=100, pre_turns=0.2, post_turns=(0.4, 0.6), time_ns=0.2, plots=False,
                       member_root=tmp_path / "m", P_nm=29.7, P_err_nm=3.0, bracket=False)
    assert not r["plateau"]["both_plectonemic"] and not r["passed"]
    assert r["pre_buckling"]["passed"]  # the linear torque law holds before buckling


@pytest.mark.slow
def test_buckling_check_runs_and_fails_before_buckling(tmp_path):
    """600 bp, 6 ns members: the check computes the two-phase comparison and fails with unbuckled members.

    (Whether the model follows the two-phase model is open: 30-ns members keep relaxing; docs/protocols.md.)
    """
    from buckling_check import check_buckling

    opts = dict(n_bp=600, time_ns=6.0, plots=False, member_root=tmp_path / "m", bracket=False, ring_pair=False)
    good = check_buckling(tmp_path, **opts)
    assert good["plateau"]["both_plectonemic"] and np.isfinite(good["marko"]["torque_pN_nm"])
    bad = check_buckling(tmp_path, post_turns=(0.379, 0.76), **opts)
    assert not bad["passed"]


@pytest.mark.slow  # research check, several seconds of MD: run with -m slow
def test_above_twins_start_from_the_larger_plectoneme_of_their_source(tmp_path):
    """bracket_start='above': one source member with more turns runs first; each post-buckling twin starts from its
    final pose with the extra turns taken out (same Lk as the straight twin, the source's pose recorded); a twin
    whose source has not run is refused with one line."""
    import numpy as np

    from dnarod.core.errors import DnarodError
    from dnarod.workflows.protocols.poses import FINAL_POSE, START_POSE, load_pose
    from buckling_check import member_plan, run_planned

    plan = member_plan(n_bp=100, pre_turns=0.2, post_turns=(0.4, 0.6), time_ns=0.02, pre_time_ns=0.02, P_nm=29.7,
                       bracket=True, above_ns=0.02)
    roles = [e["role"] for e in plan]
    assert roles.index("above_source") < roles.index("post_above")
    src = next(e for e in plan if e["role"] == "above_source")
    assert src["settings"]["turns"] == pytest.approx(0.095 * 9.4286, abs=1e-3)  # 95 % of the largest sigma (Lk0 9.43 at 100 bp)
    twin = next(e for e in plan if e["role"] == "post_above")
    assert twin["start_from"] == src["folder"] and twin["settings"]["previous_turns"] == src["settings"]["turns"]
    with pytest.raises(DnarodError, match="has not run"):
        run_planned(twin, tmp_path)
    rows = {e["folder"]: run_planned(e, tmp_path) for e in plan if e["kind"] == "tweezers"}
    straight = next(e for e in plan if e["role"] == "post" and e["index"] == twin["index"])
    assert rows[twin["folder"]]["Lk"] == pytest.approx(rows[straight["folder"]]["Lk"], abs=0.05)
    assert rows[src["folder"]]["Lk"] > rows[twin["folder"]]["Lk"] + 0.15  # the source had the extra turns
    # the twin's start: the source's final pose turned back by the extra turns (positions unchanged)
    p_src, _ = load_pose(tmp_path / src["folder"] / FINAL_POSE)
    p_twin, _ = load_pose(tmp_path / twin["folder"] / START_POSE)
    assert np.allclose(p_src, p_twin)


def test_report_says_which_P_the_buckling_check_used():
    from buckling_check import _p_label

    assert _p_label({"P_source": "closed rings of 600 and 1200 bp at sigma -0.0500: P_b = C (1 - ...)"}) \
        == "P_b (ring pair)"
    assert _p_label({"P_source": "closed ring 400 bp at sigma -0.0500: writhe fraction 0.6"}) == "P (single ring)"
    assert _p_label({"P_source": "given"}) == "P (given)"


def test_grown_twins_start_from_a_plectoneme_grown_at_a_lower_force(tmp_path):
    """bracket_start='grown' (the bracket before r7): each post-buckling twin first runs grown_ns at grown_force_pN
    (its own folder ``grow``, same turns), then from that final pose at the member's force, with the straight
    twin's linking number and the static start's equilibration."""
    from buckling_check import member_plan, run_planned
    from dnarod.workflows.protocols.poses import FINAL_POSE, START_POSE, load_pose

    plan = member_plan(n_bp=100, pre_turns=0.2, post_turns=(0.4, 0.6), time_ns=0.02, pre_time_ns=0.02, P_nm=29.7,
                       bracket=True, bracket_start="grown", grown_force_pN=0.3, grown_ns=0.02)
    grown = [e for e in plan if e["role"] == "post_grown"]
    assert len(grown) == 2 and all(e["grow"] == dict(force_pN=0.3, time_ns=0.02) for e in grown)
    twin = grown[0]
    straight = next(e for e in plan if e["role"] == "post" and e["index"] == twin["index"])
    a, b = run_planned(straight, tmp_path), run_planned(twin, tmp_path)
    assert b["Lk"] == pytest.approx(a["Lk"], abs=0.05) and b["lk_slips"] == 0
    assert b["equilibration_ps"] == pytest.approx(a["equilibration_ps"])
    folder = tmp_path / twin["folder"]
    assert json_force(folder / "grow") == pytest.approx(0.3) and json_force(folder) == pytest.approx(1.0)
    np.testing.assert_array_equal(load_pose(folder / START_POSE)[0], load_pose(folder / "grow" / FINAL_POSE)[0])


def json_force(member_dir):
    import json

    return json.loads((member_dir / "protocol_result.json").read_text())["result"]["force_pN"]
