"""The ring pair's premise in check ``buckling``: the end-loop counter of a plectoneme (synthetic shapes)."""
import numpy as np
import pytest

from dnarod.workflows.protocols.measure import plectoneme_end_loops

DS = 0.34


def _resample(waypoints, ds=DS, closed=True):
    """Points every ``ds`` nm along the polygon through ``waypoints`` (closed: back to the first)."""
    w = np.asarray(waypoints, float)
    if closed:
        w = np.vstack([w, w[:1]])
    seg = np.linalg.norm(np.diff(w, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    t = np.arange(0.0, s[-1] - (0.5 * ds if closed else -1e-9), ds)
    return np.stack([np.interp(t, s, w[:, k]) for k in range(3)], axis=1)


def star(arms, arm_nm=60.0, half_gap=2.0, hub=12.0, phase=0.0):
    """A closed chain made of ``arms`` hairpins (two duplexes 2 half_gap apart) radiating from a hub."""
    pts = []
    for k in range(arms):
        a = phase + 2 * np.pi * k / arms
        u, v = np.array([np.cos(a), np.sin(a), 0.0]), np.array([-np.sin(a), np.cos(a), 0.0])
        pts += [hub * u - half_gap * v, (hub + arm_nm) * u - half_gap * v, (hub + arm_nm) * u + half_gap * v,
                hub * u + half_gap * v]
    return _resample(pts)


@pytest.mark.parametrize("arms", [2, 3, 4])
def test_end_loops_of_a_ring_count_its_arms(arms):
    P = star(arms)
    n, where = plectoneme_end_loops(P, DS, circular=True)
    assert n == arms
    # each loop sits at the tip of an arm: the node farthest from the hub
    r = np.linalg.norm(P[:, :2], axis=1)
    for c in where:
        assert r[int(round(c)) % len(P)] > 12.0 + 55.0
    # the answer does not depend on where the ring's node 0 is
    assert plectoneme_end_loops(np.roll(P, 97, axis=0), DS, circular=True)[0] == arms


def test_end_loops_of_an_open_chain_and_of_no_plectoneme():
    hairpin = _resample([[0, 0, 0], [0, 0, 80.0], [4.0, 0, 80.0], [4.0, 0, 0], [40.0, 0, 0]], closed=False)
    n, where = plectoneme_end_loops(hairpin, DS)
    assert n == 1 and abs(where[0] - np.argmax(hairpin[:, 2] + 0.01 * hairpin[:, 0])) < 10
    straight = _resample([[0, 0, 0], [0, 0, 150.0]], closed=False)
    assert plectoneme_end_loops(straight, DS)[0] == 0
    circle = np.stack([np.cos(t := np.linspace(0, 2 * np.pi, 600, endpoint=False)), np.sin(t), 0 * t], 1) * 32.5
    assert plectoneme_end_loops(circle, DS, circular=True)[0] == 0


def _ring_dir(path, wr, loops=None):
    path.mkdir()
    cols = {"time_ps": np.arange(len(wr)) * 200.0, "Wr": wr}
    if loops is not None:
        cols["end_loops"] = loops
    lines = [",".join(cols)] + [",".join(f"{cols[c][i]:.10g}" for c in cols) for i in range(len(wr))]
    (path / "samples.csv").write_text("\n".join(lines) + "\n")
    return path


def test_ring_pair_premise_fails_on_a_branched_or_drifting_ring(tmp_path):
    from dnarod.validate.buckling import ring_pair_premise

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


def test_members_run_in_advance_from_the_plan_are_reused_by_the_check(tmp_path, monkeypatch):
    """member_plan gives exactly the members check_buckling runs (the check itself is shown reusing them in
    test_supercoiling): the recorded members' folders and settings are found, nothing is simulated (the
    samplers are disabled here)."""
    import shutil
    from pathlib import Path

    import dnarod.workflows.protocols.rings as rings
    import dnarod.workflows.protocols.tweezers as tweezers
    from dnarod.validate.buckling import member_plan, run_planned

    root = tmp_path / "members"
    shutil.copytree(Path(__file__).parent / "data" / "supercoil" / "buckling_600bp", root)
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


def test_loop_corrected_ring_pair_recovers_the_bulk_P():
    """Rings whose writhe is a bulk share of ΔLk less a fixed deficit per end loop: with different loop counts
    the pair formula is biased, the loop-counted one is exact, and with equal counts the two coincide."""
    from dnarod.physics.theory.supercoil import plectoneme_P_from_ring_pair, plectoneme_P_from_rings_with_loops

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


def test_above_twins_start_from_the_larger_plectoneme_of_their_source(tmp_path):
    """bracket_start='above': one source member with more turns runs first; each post-buckling twin starts from its
    final pose with the extra turns taken out (same Lk as the straight twin, the source's pose recorded); a twin
    whose source has not run is refused with one line."""
    import numpy as np

    from dnarod.core.errors import DnarodError
    from dnarod.workflows.protocols.poses import FINAL_POSE, START_POSE, load_pose
    from dnarod.validate.buckling import member_plan, run_planned

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


def test_equilibration_start_cuts_a_transient_and_keeps_a_stationary_series():
    """Chodera's rule on AR(1) noise (correlation time 10 samples), five seeds: a decaying start (5 sigma, 1/e over
    100 samples) is cut past 1.5 decay times (down to 1.1 sigma), a stationary series keeps at least 3/4 of its
    samples (the rule may drop a noisy stretch, never the bulk)."""
    from dnarod.validate.buckling import equilibration_start

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
