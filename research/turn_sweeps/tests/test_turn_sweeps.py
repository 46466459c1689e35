"""Turn sweeps (research/turn_sweeps; until 2026-12-07 the start modes sweep, sweep-in and bracket of
``dnarod protocol hat|torque-turns``): chains of tweezers members that continue each other's final poses, the
inward sweep's grown heads, the long settle past Marko's buckling point, the bracket's midpoint and gap error,
and bad input (one line, exit status 2, nothing written)."""
import json

import numpy as np
import pytest

import turn_sweep
from dnarod.core.errors import DnarodError
from dnarod.core.forcefield import load_forcefield
from dnarod.core.units import PN, kT
from dnarod.workflows.protocols.poses import add_turns, load_pose
from turn_sweep import bracket_rows, buckling_estimate, buckling_turns, member_settles, run_turn_sweep, sweep_chains

FF = load_forcefield("dna-default")


def hat(turns, out, force_pN=2.0, source="60", base=None, kind="magnetic_tweezers", **kw):
    """A hat curve run as turn sweeps in this process (as ``hat_curve`` ran it with a sweep start)."""
    return run_turn_sweep(kind, {"force_pN": list(np.atleast_1d(force_pN)), "turns": list(turns)},
                          dict(base or {}, source=str(source)), out, workers=0, **kw)


def cli(argv, capsys):
    """``turn_sweep.py ARGV`` in this process: (exit status, stdout, stderr)."""
    try:
        code = turn_sweep.main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.slow  # research check, several seconds of MD: run with -m slow
def test_turn_sweep_chains_members_and_resumes(tmp_path, monkeypatch):
    """start='sweep': turns >= 0 run up from 0 and turns < 0 down from the largest; each chained member starts
    from the previous member's final pose turned by the increment (its Lk follows the clamp); a second call
    reuses every finished member, and after one member's result is lost only that member runs again."""
    from dnarod.workflows.protocols import tweezers as tw

    assert sweep_chains([0.8, -0.4, 0, -1.2, 0.4]) == [[0.0, 0.4, 0.8], [-0.4, -1.2]]
    kw = dict(start="sweep", settle_ns=0.005, base=dict(time_ns=0.02, equilibration_ns=0.01, seed=3, sample_ps=2.0))
    out = tmp_path / "hat"
    c = hat([-0.5, -0.25, 0.0, 0.25, 0.5], out, **kw)
    rows = {r["turns"]: r for r in c.rows}
    mem = out / "members"
    name = {t: f"force_pN+2_turns{t:+g}" for t in rows}
    for first in (0.0, -0.25):
        assert not (mem / name[first] / "start_pose.npz").exists() and "static" in rows[first]["start"]
        assert rows[first]["previous_turns"] is None
    for t, prev in ((0.25, 0.0), (0.5, 0.25), (-0.5, -0.25)):
        P, F = add_turns(*load_pose(mem / name[prev] / "final_pose.npz"), t - prev)
        P1, F1 = load_pose(mem / name[t] / "start_pose.npz")
        np.testing.assert_array_equal(P1, P)
        np.testing.assert_array_equal(F1, F)
        assert rows[t]["previous_turns"] == prev and "turn sweep" in rows[t]["start"]
        assert rows[t]["equilibration_ps"] == pytest.approx(5.0)
    for t, r in rows.items():
        assert r["lk_slips"] == 0 and r["delta_lk"] == pytest.approx(r["end_turns"], abs=0.02)
        assert abs(r["end_turns"] - t) < 0.05
    assert c.files["csv"].exists() and c.files["png"].exists() and (out / "protocol.json").exists()
    # every member its own noise stream, derived reproducibly from the curve's seed, force, turns and direction
    from dnarod.workflows.protocols.ensemble_hooks import member_seed

    seeds = {t: r["seed"] for t, r in rows.items()}
    assert len(set(seeds.values())) == len(seeds)
    for t, sd in seeds.items():
        assert sd == member_seed(member_seed(3, "magnetic_tweezers", 2.0, t), "sweep")
    calls = []
    real = tw.sample_member
    monkeypatch.setattr(tw, "sample_member", lambda *a, **k: calls.append(a[0]["turns"]) or real(*a, **k))
    again = hat([-0.5, -0.25, 0.0, 0.25, 0.5], out, **kw)
    assert calls == [] and [r["wall_s"] for r in again.rows] == [r["wall_s"] for r in c.rows]
    (mem / name[0.5] / "protocol_result.json").unlink()
    hat([-0.5, -0.25, 0.0, 0.25, 0.5], out, **kw)
    assert calls == [0.5]


def test_turn_sweep_bad_input(tmp_path):
    """A sweep of a protocol without a rotation clamp, a settle time <= 0 or longer than a member may run, and an
    unknown start (the product's own starts included) are refused before anything is written."""
    with pytest.raises(DnarodError, match="rotation-clamp"):
        hat([1.0], tmp_path / "a", source="40", kind="force_extension", start="sweep")
    with pytest.raises(DnarodError, match="ns > 0"):
        hat([0.0], tmp_path / "b", source="40", start="sweep", settle_ns=-1.0)
    with pytest.raises(DnarodError, match="10000 ns"):
        hat([0.0], tmp_path / "c", source="40", start="sweep", settle_ns=1e9)
    for start in ("ramp", "static"):
        with pytest.raises(DnarodError, match="choose 'sweep'"):
            hat([0.0], tmp_path / "d", source="40", start=start)
    assert not any((tmp_path / x).exists() for x in "abcd")


@pytest.mark.slow  # research check, several seconds of MD: run with -m slow
def test_inward_turn_sweep_starts_from_a_grown_plectoneme(tmp_path, monkeypatch):
    """start='sweep-in': chains run towards zero turns; each head starts from a plectoneme grown at a lower force
    (same Lk) and the next member from the head's final pose with the turns taken out."""
    from dnarod.workflows.protocols.ensemble_hooks import member_seed

    assert sweep_chains([0.8, -0.4, 0, -1.2, 0.4], inward=True) == [[0.8, 0.4, 0.0], [-1.2, -0.4]]
    monkeypatch.setattr(turn_sweep, "GROW_NS", 0.01)
    c = hat([-0.5, 0.5, 0.25], tmp_path / "in", start="sweep-in",
            base=dict(time_ns=0.02, equilibration_ns=0.01, seed=3, sample_ps=2.0))
    rows = {r["turns"]: r for r in c.rows}
    assert "grown plectoneme" in rows[0.5]["start"] and "grown plectoneme" in rows[-0.5]["start"]
    assert rows[0.25]["previous_turns"] == 0.5 and "turn sweep" in rows[0.25]["start"]
    mem = tmp_path / "in" / "members"
    # the head: grown 0.01 ns at 0.3 x 2 pN (its own folder), then run from that pose at the member's force
    head, grow = mem / "force_pN+2_turns+0.5", mem / "force_pN+2_turns+0.5" / "grow"
    assert json.loads((grow / "protocol_result.json").read_text())["result"]["force_pN"] == pytest.approx(0.6)
    np.testing.assert_array_equal(load_pose(head / "start_pose.npz")[1], load_pose(grow / "final_pose.npz")[1])
    P, F = add_turns(*load_pose(head / "final_pose.npz"), -0.25)
    np.testing.assert_array_equal(load_pose(mem / "force_pN+2_turns+0.25" / "start_pose.npz")[1], F)
    for t, r in rows.items():
        assert r["lk_slips"] == 0 and abs(r["end_turns"] - t) < 0.05
    for t, r in rows.items():  # not the outward sweep's stream at the same turns
        base = member_seed(3, "magnetic_tweezers", 2.0, t)
        assert r["seed"] == member_seed(base, "sweep-in") != member_seed(base, "sweep")


def test_grown_start_keeps_the_linking_number(tmp_path):
    """A tweezers member begun from a plectoneme grown at a lower force has the straight start's Lk (same turns
    and clamp), and equilibrates as long as a static start unless told otherwise."""
    from dnarod.workflows.protocols.tweezers import run_member

    base = dict(n_bp=100, force_pN=1.0, turns=0.8, time_ns=0.02, equilibration_ns=0.01, seed=3)
    a = run_member(base, tmp_path / "straight")
    b = turn_sweep.run_grown_member(base, tmp_path / "grown", 0.2, 0.05)
    assert a["lk_slips"] == 0 and b["lk_slips"] == 0
    assert b["Lk"] == pytest.approx(a["Lk"], abs=0.05) and "grown plectoneme" in b["start"]
    assert b["equilibration_ps"] == pytest.approx(a["equilibration_ps"])
    no_eq = {k: v for k, v in base.items() if k != "equilibration_ns"}
    c = turn_sweep.run_grown_member(dict(no_eq, time_ns=0.005), tmp_path / "grown_default", 0.2, 0.01)
    d = run_member(dict(no_eq, time_ns=0.005), tmp_path / "straight_default")
    assert c["equilibration_ps"] == pytest.approx(d["equilibration_ps"])  # five slowest bending relaxation times


def test_buckling_turns_place_marko_buckling_point():
    """The long settle starts at margin x Marko's buckling Delta Lk (the model's A, Moroz-Nelson C_s, P), counted
    from the relaxed linking number at T: for 1 kbp at 1 pN Delta Lk_b = 1.78 turns (the 1.76 of the buckling
    check's theory), and the hat's centre is at -0.42 turns (0.42 milliturn per step)."""
    import math

    from dnarod.physics.theory.supercoil import wlc_free_energy_exact

    e = buckling_estimate("1000", 1.0, 300.0)
    kt = kT(300.0) / PN
    A, C = 50.0, 98.25
    M, K0 = C / A, math.sqrt(A * 1.0 / kt)  # Moroz & Nelson 1998 to third order in 1/K0, written out here
    c_s = C * (1 - M / (4 * K0) + (M * M - 2 * M) / (16 * K0 ** 2) - (4 * M ** 3 - 16 * M * M + 21 * M) / (256 * K0 ** 3))
    tau = math.sqrt(2 * kt * wlc_free_energy_exact(1.0, A, kt) / (1 / 17.3 - 1 / c_s))
    L = 999 * FF.model_from_sequence(n_nodes=10).ds
    assert e["C_s_nm"] == pytest.approx(c_s, rel=1e-3)
    assert e["buckling_delta_lk"] == pytest.approx(tau * L / (2 * math.pi * kt * c_s), rel=1e-3)
    assert 1.70 < e["buckling_delta_lk"] < 1.85
    assert 0.38e-3 < e["thermal_offset_turns"] / 999 < 0.46e-3
    lo, hi = buckling_turns("1000", 1.0)
    assert hi == pytest.approx(0.8 * e["buckling_delta_lk"] - e["thermal_offset_turns"])
    assert lo == pytest.approx(-0.8 * e["buckling_delta_lk"] - e["thermal_offset_turns"])
    assert -1.9 < lo < -1.8 and 0.95 < hi < 1.05
    turns = [-4.8, -4, -3.2, -2.4, -1.6, -0.8, 0, 0.8, 1.6, 2.4, 3.2, 4]
    assert member_settles(turns, 8.0, 60.0, (lo, hi)) == [60.0] * 4 + [8.0] * 4 + [60.0] * 4
    assert member_settles(turns, 8.0, None, (lo, hi)) == [8.0] * 12
    assert buckling_estimate("1000", 4.0)["buckling_delta_lk"] > e["buckling_delta_lk"]  # buckles later at 4 pN
    with pytest.raises(DnarodError, match="margin"):
        buckling_estimate("100", 1.0, margin=1.5)


def test_turn_sweep_settles_long_only_past_buckling(tmp_path):
    """settle_buckled_ns: chained members at or beyond the buckling bounds settle that long, the others settle_ns,
    the chain heads their equilibration; the rows carry the bounds."""
    lo, hi = buckling_turns("60", 2.0)
    assert -0.25 < lo < -0.1 and 0.05 < hi < 0.15
    c = hat([-0.25, -0.1, 0.0, 0.05, 0.2], tmp_path / "hat", start="sweep", settle_ns=0.004, settle_buckled_ns=0.012,
            base=dict(time_ns=0.01, equilibration_ns=0.008, seed=3, sample_ps=2.0))
    eq = {r["turns"]: r["equilibration_ps"] for r in c.rows}
    assert eq == {0.0: pytest.approx(8.0), -0.1: pytest.approx(8.0), 0.05: pytest.approx(4.0),
                  0.2: pytest.approx(12.0), -0.25: pytest.approx(12.0)}
    assert all(r["buckled_settle_from_turns_hi"] == pytest.approx(hi) for r in c.rows)


def test_settle_buckled_bad_input(tmp_path, capsys):
    """--settle-buckled <= 0 or not finite, --settle longer than a member may run, an unknown start: one line,
    exit 2, nothing written (the API and the command line alike)."""
    with pytest.raises(DnarodError, match="settle_buckled 0.0: give a time in ns > 0"):
        hat([0.0], tmp_path / "a", source="40", start="sweep", settle_buckled_ns=0.0)
    with pytest.raises(DnarodError, match="settle_buckled nan: give a time in ns > 0"):
        hat([0.0], tmp_path / "b", source="40", start="sweep", settle_buckled_ns=float("nan"))
    base = ["hat", "--source", "40", "--turns", "0,0.2", "--time", "0.01", "--workers", "0"]
    for extra, msg in ((["--settle-buckled", "-1"], "give a time in ns > 0"),
                       (["--settle-buckled", "nan"], "give a time in ns > 0"),
                       (["--settle", "1e9"], "10000 ns"),
                       (["--start", "static"], "invalid choice: 'static'"),
                       (["--turns", "one"], "comma-separated numbers")):
        code, out, err = cli([*base, *extra, "-o", tmp_path / "c"], capsys)
        assert code == 2 and msg in err and "Traceback" not in err and out == "", (code, out, err)
        assert len(err.strip().splitlines()) == 1, err
    assert not any((tmp_path / x).exists() for x in "abc")


def test_bracket_rows_midpoint_and_gap_error():
    """A bracketed point is the midpoint of its outward and inward members; its error covers half their gap and
    their own errors, sqrt(((a-b)/2)^2 + (ea^2 + eb^2)/4); the gap's z and the relative half-gap are reported;
    costs add up; a turn value with one direction only is refused."""
    import math

    out = [dict(force_pN=1.0, turns=2.4, relative_extension=0.70, relative_extension_err=0.01, Wr=1.0, Wr_err=0.1,
                cpu_s=100.0, wall_s=120.0, n_steps=10, start="s1", seed=1, sweep_direction="out"),
           dict(force_pN=1.0, turns=0.0, relative_extension=0.87, relative_extension_err=0.004, cpu_s=50.0,
                wall_s=60.0, n_steps=5, start="s0", seed=2, sweep_direction="out")]
    inn = [dict(force_pN=1.0, turns=2.4, relative_extension=0.62, relative_extension_err=0.02, Wr=1.4, Wr_err=0.1,
                cpu_s=200.0, wall_s=210.0, n_steps=20, start="s2", seed=3, sweep_direction="in"),
           dict(force_pN=1.0, turns=0.0, relative_extension=0.87, relative_extension_err=0.003, cpu_s=40.0,
                wall_s=45.0, n_steps=4, start="s3", seed=4, sweep_direction="in")]
    rows = bracket_rows(out, inn)
    assert [r["turns"] for r in rows] == [0.0, 2.4]
    r0, r = rows
    assert r["relative_extension"] == pytest.approx(0.66)
    assert r["relative_extension_err"] == pytest.approx(math.sqrt(0.04 ** 2 + (0.01 ** 2 + 0.02 ** 2) / 4))
    assert r["relative_extension_gap_z"] == pytest.approx(0.08 / math.hypot(0.01, 0.02))
    assert r["relative_extension_half_gap_rel"] == pytest.approx(0.04 / 0.66)
    assert r["relative_extension_rel_err"] == pytest.approx(r["relative_extension_err"] / 0.66)
    assert (r["relative_extension_out"], r["relative_extension_in"]) == (0.70, 0.62)
    assert r["Wr"] == pytest.approx(1.2) and r["Wr_err"] == pytest.approx(math.sqrt(0.2 ** 2 + 0.005))
    assert (r["cpu_s"], r["wall_s"], r["n_steps"]) == (300.0, 330.0, 30)
    assert (r["start_out"], r["start_in"], r["seed_out"], r["seed_in"]) == ("s1", "s2", 1, 3)
    # two agreeing members: the error is the statistical one alone
    assert r0["relative_extension_err"] == pytest.approx(math.hypot(0.004, 0.003) / 2)
    with pytest.raises(DnarodError, match=r"one sweep direction only"):
        bracket_rows(out, inn[:1])


def test_bracket_start_runs_both_sweeps(tmp_path, monkeypatch):
    """start='bracket': the outward and inward sweeps run in one call (members out_* and in_*, both in
    members.csv); each curve point combines the two members at its turn value exactly as bracket_rows does; a
    chain head past buckling (the inward heads here) equilibrates for settle_buckled_ns; bad input is refused."""
    monkeypatch.setattr(turn_sweep, "GROW_NS", 0.01)
    out = tmp_path / "b"
    c = hat([-0.5, 0.0, 0.5], out, start="bracket", settle_ns=0.005, settle_buckled_ns=0.016,
            base=dict(time_ns=0.02, equilibration_ns=0.01, seed=3, sample_ps=2.0))
    names = sorted(p.name for p in (out / "members").iterdir())
    assert names == sorted(f"{d}_force_pN+2_turns{t}" for d in ("in", "out") for t in ("+0", "+0.5", "-0.5"))
    members = {}
    for p in (out / "members").iterdir():
        r = json.loads((p / "protocol_result.json").read_text())["result"]
        members[(p.name[:p.name.index("_")], r["turns"])] = r
    # the inward heads (+-0.5 turns: past this chain's buckling bounds) equilibrate 16 ps, the outward heads 10 ps
    assert members[("in", 0.5)]["equilibration_ps"] == pytest.approx(16.0, rel=0.02)
    assert members[("in", -0.5)]["equilibration_ps"] == pytest.approx(16.0, rel=0.02)
    assert members[("out", 0.0)]["equilibration_ps"] == pytest.approx(10.0, rel=0.02)
    assert (out / "members" / "in_force_pN+2_turns+0.5" / "grow" / "final_pose.npz").exists()
    rows = {r["turns"]: r for r in c.rows}
    assert "grown plectoneme" in rows[0.5]["start_in"] and "static" in rows[0.0]["start_out"]
    assert sorted(rows) == [-0.5, 0.0, 0.5]
    for t, r in rows.items():
        a, b = members[("out", t)], members[("in", t)]
        assert r["relative_extension_out"] == pytest.approx(a["relative_extension"])
        assert r["relative_extension_in"] == pytest.approx(b["relative_extension"])
        assert r["relative_extension"] == pytest.approx(0.5 * (a["relative_extension"] + b["relative_extension"]))
        assert r["cpu_s"] == pytest.approx(a["cpu_s"] + b["cpu_s"])
        # the twisting moment of the point and of both members on the model's zero-torque offset
        off = r["twist_torque_offset_pN_nm"]
        assert r["twist_torque_pN_nm_out"] == pytest.approx(a["twist_torque_pN_nm"] - off)
        assert r["twist_torque_pN_nm_in"] == pytest.approx(b["twist_torque_pN_nm"] - off)
        assert r["twist_torque_pN_nm"] == pytest.approx(0.5 * (a["twist_torque_pN_nm"] + b["twist_torque_pN_nm"]) - off)
    expect = bracket_rows([dict(m, force_pN=2.0) for (d, _), m in members.items() if d == "out"],
                          [dict(m, force_pN=2.0) for (d, _), m in members.items() if d == "in"])
    assert [e["relative_extension_err"] for e in expect] == pytest.approx(
        [rows[t]["relative_extension_err"] for t in sorted(rows)])
    assert (out / "members.csv").read_text().count("\n") == 7  # header + six members
    with pytest.raises(DnarodError, match="rotation-clamp"):
        hat([1.0], tmp_path / "fe", source="40", kind="force_extension", start="bracket")
    with pytest.raises(DnarodError, match="ns > 0"):
        hat([0.0], tmp_path / "neg", source="40", start="bracket", settle_buckled_ns=0.0)
