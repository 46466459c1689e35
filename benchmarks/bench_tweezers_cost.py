"""Where a 1-kbp tweezers member's time goes: each OpenMM force of the member (force-group timing), the step with
and without the surface and bead walls, an exact alternative form of the bead wall, and the per-sample observables.

One member's System as the protocol builds it (1000 bp, 1 pN, +3 turns, WCA + Debye-Hueckel, rotation clamp,
compiled plugin where built, one thread): (1) every force in its own force group, ``Context.getState(getForces,
groups=...)`` timed per force on a copy of the System with a plain Verlet integrator; (2) steps per CPU-second of
the member's own integrator with no walls, the surface wall only, both walls (the protocol's form), and the bead wall
written as a ``CustomCompoundBondForce`` over (node i, the last node's three particles) instead of a
``CustomCentroidBondForce`` (the same energy: checked here to 1e-9 relative on energy and forces); (3) CPU time of
the observables computed per sample (end rotation, Tw/Wr, plectoneme detector, twisting moment). Prints a table and
writes ``benchmarks/results/tweezers_cost.json``.

    python benchmarks/bench_tweezers_cost.py [--n-bp 1000] [--steps 2000]
"""
from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np


def bead_wall_compound(model, k, skip):
    """The bead wall of :func:`dnarod.protocols.tweezers.tweezers_wall_forces` as a CustomCompoundBondForce."""
    import openmm

    n = model.n_nodes
    b = openmm.CustomCompoundBondForce(4, "0.5*dnarod_bead_k*max(0, z1 - (z2 + z3 + z4)/3)^2")
    b.addGlobalParameter("dnarod_bead_k", float(k))
    last = 3 * (n - 1)
    for i in range(n - skip):
        b.addBond([3 * i, last, last + 1, last + 2], [])
    return b


def force_group_times(sim, repeats):
    """CPU seconds per evaluation of each force of ``sim``'s System, alone (own force group, Verlet Context)."""
    import openmm

    system = openmm.XmlSerializer.deserialize(openmm.XmlSerializer.serialize(sim.rs.system))
    names = []
    for g, f in enumerate(system.getForces()):
        f.setForceGroup(g)
        names.append(f.getName() or type(f).__name__)
    ctx = openmm.Context(system, openmm.VerletIntegrator(0.001), sim.context.getPlatform(),
                         {"Threads": "1"} if sim.context.getPlatform().getName() == "CPU" else {})
    st = sim.context.getState(getPositions=True)
    ctx.setPositions(st.getPositions())
    out = []
    empty = len(names)  # a force group with no force: the cost of getState itself, subtracted below
    c0 = time.process_time()
    for _ in range(repeats):
        ctx.getState(getForces=True, getEnergy=True, groups={empty})
    base = 1e6 * (time.process_time() - c0) / repeats
    out.append(dict(force="(empty group: getState overhead)", type="", us_per_evaluation=base, us_net=0.0))
    for g, name in enumerate(names):
        ctx.getState(getForces=True, getEnergy=True, groups={g})
        c0 = time.process_time()
        for _ in range(repeats):
            ctx.getState(getForces=True, getEnergy=True, groups={g})
        us = 1e6 * (time.process_time() - c0) / repeats
        out.append(dict(force=name, type=type(system.getForce(g)).__name__, us_per_evaluation=us, us_net=us - base))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-bp", type=int, default=1000)
    ap.add_argument("--force", type=float, default=1.0)
    ap.add_argument("--turns", type=float, default=3.0)
    ap.add_argument("--time", type=float, default=40.0, help="production (ns) that sets the sampling interval")
    ap.add_argument("--steps", type=int, default=2000, help="steps per rate measurement (best of 3)")
    ap.add_argument("--platform", default="CPU")
    ap.add_argument("--out", default="benchmarks/results/tweezers_cost.json")
    a = ap.parse_args(argv)
    import openmm

    from dnarod.openmm.nonbonded import NonbondedSettings
    from dnarod.openmm.simulation import RodSimulation
    from dnarod.protocols import tweezers as tw
    from dnarod.protocols.measure import plectoneme_state, rotation_about_z, twist_writhe_open, twisting_moment

    m = tw.build_member(dict(n_bp=a.n_bp, force_pN=a.force, turns=a.turns, time_ns=a.time, equilibration_ns=0.1))
    model = m["model"]
    nb = NonbondedSettings(excluded_volume=True, electrostatics=True, salt=0.15)

    def make(extra):
        return RodSimulation(model, temperature=300.0, friction=m["friction"], platform=a.platform, nonbonded=nb,
                             loads=m["loads"], seed=1, threads=1, elastic="auto", extra_forces=extra)

    def rate(sim):
        sim.advance(100)
        best = 0.0
        for _ in range(3):
            c0 = time.process_time()
            sim.advance(a.steps)
            best = max(best, a.steps / (time.process_time() - c0))
        return best

    variants = {}
    sims = {}
    for name in ("no walls", "surface wall only", "both walls (protocol)", "both walls, bead as compound bond"):
        walls = tw.tweezers_wall_forces(model)
        extra = {"no walls": [], "surface wall only": walls[:1], "both walls (protocol)": walls,
                 "both walls, bead as compound bond": [walls[0], bead_wall_compound(model, tw.WALL_K, tw.WALL_SKIP)]
                 }[name]
        sim = make(extra)
        sims[name] = sim
        r = rate(sim)
        variants[name] = dict(steps_per_cpu_s=r, us_per_step=1e6 / r, ns_per_cpu_day=r * sim.dt * 1e-3 * 86400.0,
                              elastic_path=sim.rs.elastic, platform=sim.platform_name)
    # the two bead forms: same energy and forces on a thermal configuration with nodes pushed through the bead plane
    import copy

    sim = sims["both walls (protocol)"]
    pos = sim.context.getState(getPositions=True).getPositions(asNumpy=True)._value.copy()
    zl = pos[-3:, 2].mean()
    pos[3 * 100:3 * 110, 2] = zl + 0.3  # ten nodes' particles above the bead plane
    diffs = {}
    for form in ("centroid", "compound"):
        sysb = openmm.System()
        for _ in range(len(pos)):
            sysb.addParticle(1.0)
        f = (tw.tweezers_wall_forces(model)[1] if form == "centroid"
             else bead_wall_compound(model, tw.WALL_K, tw.WALL_SKIP))
        sysb.addForce(copy.deepcopy(f))
        ctx = openmm.Context(sysb, openmm.VerletIntegrator(0.001), openmm.Platform.getPlatformByName("Reference"))
        ctx.setPositions(pos)
        st = ctx.getState(getEnergy=True, getForces=True)
        diffs[form] = (st.getPotentialEnergy()._value, st.getForces(asNumpy=True)._value)
    e1, f1 = diffs["centroid"]
    e2, f2 = diffs["compound"]
    same = dict(energy_centroid=e1, energy_compound=e2, energy_rel_diff=abs(e1 - e2) / abs(e1),
                force_max_abs_diff=float(np.abs(f1 - f2).max()), force_max=float(np.abs(f1).max()))
    assert same["energy_rel_diff"] < 1e-9 and same["force_max_abs_diff"] < 1e-9 * same["force_max"]
    groups = force_group_times(sim, repeats=max(50, a.steps // 10))
    # observables per sample (on the protocol member's current state)
    pos_n, frm = sim.node_pose()
    obs = {}
    for name, fn in (("node_pose", lambda: sim.node_pose()),
                     ("end rotation", lambda: rotation_about_z(frm[-1], m["ref_frame"])),
                     ("Tw, Wr (closed polygon writhe)", lambda: twist_writhe_open(pos_n, frm)),
                     ("plectoneme detector", lambda: plectoneme_state(pos_n, model.ds, return_mask=True)),
                     ("twisting moment", lambda: twisting_moment(pos_n, frm, model.params, model.ds))):
        fn()
        c0 = time.process_time()
        for _ in range(20):
            sim.invalidate() if name == "node_pose" else None
            fn()
        obs[name] = 1e3 * (time.process_time() - c0) / 20
    dt = sim.dt
    per_sample_steps = m["sample_ps"] / dt
    out = dict(date=time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), load_average=os.getloadavg(), n_bp=a.n_bp,
               force_pN=a.force, turns=a.turns, dt_ps=dt, steps_per_measurement=a.steps, variants=variants,
               bead_forms_same_energy=same, force_group_us=groups, observables_ms_per_sample=obs,
               default_sample_ps=m["sample_ps"],
               observables_share_at_default_sampling=sum(obs.values()) * 1e-3 /
               (sum(obs.values()) * 1e-3 + per_sample_steps / variants["both walls (protocol)"]["steps_per_cpu_s"]))
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps(out, indent=1) + "\n")
    print(f"{a.n_bp} bp at {a.force} pN, {a.turns} turns, {sim.rs.elastic} on {sim.platform_name}, dt {dt:.4f} ps, "
          f"load average {out['load_average'][0]:.1f}")
    for k, v in variants.items():
        print(f"  {k:38s} {v['steps_per_cpu_s']:7.0f} steps/CPU-s  {v['us_per_step']:6.1f} us/step  "
              f"{v['ns_per_cpu_day']:7.0f} ns/CPU-day")
    print(f"  bead wall, centroid vs compound form: energy rel. diff {same['energy_rel_diff']:.1e}, "
          f"force max diff {same['force_max_abs_diff']:.1e} (max force {same['force_max']:.3g})")
    print("  each force alone (own force group, getState):")
    for g in groups:
        print(f"    {g['force']:46s} {g['type']:24s} {g['us_per_evaluation']:8.1f} us ({g['us_net']:6.1f} net)")
    print("  observables per sample (ms): " + ", ".join(f"{k} {v:.2f}" for k, v in obs.items()))
    print(f"  observables' share of the CPU time at the default sampling ({m['sample_ps']:g} ps): "
          f"{100 * out['observables_share_at_default_sampling']:.1f} %")


if __name__ == "__main__":
    main()
