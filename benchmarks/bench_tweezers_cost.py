"""Where a 1-kbp tweezers member's time goes: each OpenMM force of the member (force-group timing), the step with
and without the surface and bead walls in both their forms, why the Custom-force walls are slow, the per-sample
observables and the cost of a whole member with either wall form.

One member's System as the protocol builds it (1000 bp, 1 pN, +3 turns, WCA + Debye-Hueckel, rotation clamp,
compiled plugin where built, one thread): (1) every force in its own force group, ``Context.getState(getForces,
groups=...)`` timed per force on a copy of the System with a plain Verlet integrator; (2) steps per CPU-second of
the member's own integrator with no walls, the surface wall only and both walls as OpenMM Custom forces (the
reference form, :func:`dnarod.engines.openmm.walls.wall_forces_reference`: the protocol's form before the compiled one),
and both walls as the compiled ``WallForce`` (:func:`dnarod.engines.openmm.walls.wall_forces_compiled`, the protocol's
form on CPU/Reference now), with the two forms' energies and forces compared on a thermal configuration pushed through
both walls; (3) why the Custom forces cost what they do: a ``CustomExternalForce`` and a
``CustomCentroidBondForce`` alone on the CPU platform with 0, 1 and 3 particles (bonds) per node, and the walls
alone in each candidate form (Custom forces, compiled ``WallForce``, the numba kernel in its ``PythonForce``) on
the CPU and Reference platforms, and the step of the Python-callback elastic path (``elastic="fast"``, where the
plugin is not built) with no walls and each wall form; (4) CPU time of
the observables computed per sample (end rotation, Tw/Wr, plectoneme detector, twisting moment); (5) a whole
member (``--member-ns`` of production after 0.1 ns of equilibration, ``sample_member``) with each wall form.
Prints a table and writes ``benchmarks/results/tweezers_cost.json``.

    python benchmarks/bench_tweezers_cost.py [--n-bp 1000] [--steps 2000] [--member-ns 10]
"""
from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np



def _net_force_cost_us(forces, x, platform, repeats):
    """CPU µs per evaluation of ``forces`` (put in group 1) on particles at ``x`` (n, 3) nm, net of an evaluation
    of the empty group 0, on one thread of ``platform``."""
    import openmm

    s = openmm.System()
    for _ in range(len(x)):
        s.addParticle(1.0)
    for f in forces:
        f.setForceGroup(1)
        s.addForce(f)
    ctx = openmm.Context(s, openmm.VerletIntegrator(0.001), openmm.Platform.getPlatformByName(platform),
                         {"Threads": "1"} if platform == "CPU" else {})
    ctx.setPositions(x)
    out = []
    for g in ({0}, {1}):
        ctx.getState(getForces=True, getEnergy=True, groups=g)
        c0 = time.process_time()
        for _ in range(repeats):
            ctx.getState(getForces=True, getEnergy=True, groups=g)
        out.append(1e6 * (time.process_time() - c0) / repeats)
    return out[1] - out[0]

def custom_force_costs(n_nodes, repeats):
    """CPU microseconds per evaluation of the reference walls' Custom forces alone (CPU platform, one thread) on a
    System of ``3 n_nodes`` particles, with 0, 1 and 3 particles per node (surface) and 0 and 1 bonds per node
    (bead), net of an empty force group."""
    import openmm

    n = 3 * n_nodes
    rng = np.random.default_rng(0)
    x = rng.normal(size=(n, 3))

    def cost(f):
        return _net_force_cost_us([f], x, "CPU", repeats)

    rows = []
    for per_node in (0, 1, 3):
        f = openmm.CustomExternalForce("0.5*k*min(0, z - z0)^2")
        f.addGlobalParameter("k", 100.0)
        f.addGlobalParameter("z0", 0.0)
        for i in range(per_node * n_nodes):
            f.addParticle(i if per_node == 3 else 3 * i, [])
        rows.append(dict(force="CustomExternalForce", terms=per_node * n_nodes, us_net=cost(f)))
    for per_node in (0, 1):
        b = openmm.CustomCentroidBondForce(2, "0.5*k*max(0, z1 - z2)^2")
        b.addGlobalParameter("k", 100.0)
        last = b.addGroup([n - 3, n - 2, n - 1], [1.0, 1.0, 1.0])
        for i in range(per_node * n_nodes):
            b.addBond([b.addGroup([3 * i], [1.0]), last], [])
        rows.append(dict(force="CustomCentroidBondForce", terms=per_node * n_nodes, us_net=cost(b)))
    return rows


def wall_form_costs(n_nodes, repeats):
    """CPU microseconds per evaluation of the walls alone in each form (Custom forces, compiled WallForce, the numba
    kernel in its ``PythonForce``) on the CPU (one thread) and Reference platforms, net of an empty group, on
    random positions (about half the surface particles under the plane)."""

    from dnarod.engines.openmm import walls as wl

    n = 3 * n_nodes
    x = np.random.default_rng(0).normal(size=(n, 3))
    rows = []
    for plat in ("CPU", "Reference"):
        for form in ("Custom forces", "compiled WallForce", "numba PythonForce"):
            forces = {"Custom forces": lambda: wl.wall_forces_reference(n_nodes, 0.0, 100.0, 3),
                      "compiled WallForce": lambda: wl.wall_forces_compiled(n_nodes, 0.0, 100.0, 3),
                      "numba PythonForce": lambda: wl.wall_forces_numba(n_nodes, 0.0, 100.0, 3)}[form]()
            rows.append(dict(platform=plat, form=form, us_net=_net_force_cost_us(forces, x, plat, repeats)))
    return rows


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


def member_cost(a, form):
    """Wall and CPU seconds of one whole member (``sample_member``: equilibration, production, observables)."""
    import functools

    from dnarod.workflows.protocols import tweezers as tw

    settings = dict(n_bp=a.n_bp, force_pN=a.force, turns=a.turns, time_ns=a.member_ns, equilibration_ns=0.1,
                    platform=a.platform, seed=1)
    orig = tw.tweezers_wall_forces
    # the protocol picks the wall form itself; here it is pinned to one form for the comparison
    tw.tweezers_wall_forces = functools.partial(orig, form=form)
    try:
        c0, w0 = time.process_time(), time.perf_counter()
        samples, cost = tw.sample_member(tw.build_member(settings))
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    finally:
        tw.tweezers_wall_forces = orig
    return dict(form=form, production_ns=a.member_ns, equilibration_ns=0.1, n_steps=cost["n_steps"],
                n_samples=cost["n_samples"], wall_s=wall, cpu_s=cpu, member_wall_s=cost["wall_s"],
                member_cpu_s=cost["cpu_s"], us_per_step_cpu=1e6 * cost["cpu_s"] / cost["n_steps"],
                elastic_path=cost.get("elastic_path"))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-bp", type=int, default=1000)
    ap.add_argument("--force", type=float, default=1.0)
    ap.add_argument("--turns", type=float, default=3.0)
    ap.add_argument("--time", type=float, default=40.0, help="production (ns) that sets the sampling interval")
    ap.add_argument("--steps", type=int, default=2000, help="steps per rate measurement (best of 3)")
    ap.add_argument("--member-ns", type=float, default=10.0, help="production of the whole-member runs (0: none)")
    ap.add_argument("--platform", default="CPU")
    ap.add_argument("--out", default="benchmarks/results/tweezers_cost.json")
    a = ap.parse_args(argv)
    import openmm

    from dnarod.engines.openmm import walls as wl
    from dnarod.physics.nonbonded import NonbondedSettings
    from dnarod.engines.openmm.simulation import RodSimulation
    from dnarod.workflows.protocols import tweezers as tw
    from dnarod.workflows.protocols.measure import plectoneme_state, rotation_about_z, twisting_moment
    from dnarod.physics.observables import twist_writhe_open

    load0 = os.getloadavg()
    m = tw.build_member(dict(n_bp=a.n_bp, force_pN=a.force, turns=a.turns, time_ns=a.time, equilibration_ns=0.1))
    model = m["model"]
    nb = NonbondedSettings(excluded_volume=True, electrostatics=True, salt=0.15)

    def make(extra, elastic="auto"):
        return RodSimulation.create(model, temperature=300.0, friction=m["friction"], platform=a.platform, nonbonded=nb,
                             loads=m["loads"], seed=1, threads=1, elastic=elastic, extra_forces=extra)

    def rate(sim, steps=None):
        steps = a.steps if steps is None else steps
        sim.advance(100)
        best = 0.0
        for _ in range(3):
            c0 = time.process_time()
            sim.advance(steps)
            best = max(best, steps / (time.process_time() - c0))
        return best

    def forms(form):
        return tw.tweezers_wall_forces(model, platform=a.platform, form=form)

    variants = {}
    sims = {}
    names = ("no walls", "surface wall only (Custom)", "both walls, Custom forces (reference; before)",
             "both walls, compiled WallForce (protocol)")
    for name in names:
        extra = {names[0]: [], names[1]: forms("reference")[:1], names[2]: forms("reference"),
                 names[3]: forms("compiled")}[name]
        sim = make(extra)
        sims[name] = sim
        r = rate(sim)
        variants[name] = dict(steps_per_cpu_s=r, us_per_step=1e6 / r, ns_per_cpu_day=r * sim.dt * 1e-3 * 86400.0,
                              elastic_path=sim.rs.elastic, platform=sim.platform_name)
    # the Python-callback elastic path (where the plugin is not built): no walls and each wall form
    callback = {}
    for form in ("no walls", "reference", "numba", "compiled"):
        if form == "compiled" and not wl.compiled_walls_available():
            continue
        r = rate(make([] if form == "no walls" else forms(form), elastic="fast"), max(200, a.steps // 4))
        callback[form] = dict(steps_per_cpu_s=r, us_per_step=1e6 / r)
    # the two forms: same energy and forces on a thermal configuration with nodes pushed through both walls
    import copy

    sim = sims[names[3]]
    pos = sim.context.getState(getPositions=True).getPositions(asNumpy=True)._value.copy()
    zl = pos[-3:, 2].mean()
    pos[3 * 100:3 * 110, 2] = zl + 0.3  # ten nodes' particles above the bead plane
    pos[3 * 20:3 * 25, 2] = float(model.positions[0, 2]) - 0.4  # five nodes' particles under the surface
    res = {}
    for form in ("reference", "compiled"):
        sysb = openmm.System()
        for _ in range(len(pos)):
            sysb.addParticle(1.0)
        for f in forms(form):
            sysb.addForce(copy.deepcopy(f))
        ctx = openmm.Context(sysb, openmm.VerletIntegrator(0.001), openmm.Platform.getPlatformByName("Reference"))
        ctx.setPositions(pos)
        st = ctx.getState(getEnergy=True, getForces=True)
        res[form] = (st.getPotentialEnergy()._value, st.getForces(asNumpy=True)._value)
    e1, f1 = res["reference"]
    e2, f2 = res["compiled"]
    same = dict(energy_reference=e1, energy_compiled=e2, energy_rel_diff=abs(e1 - e2) / abs(e1),
                force_max_abs_diff=float(np.abs(f1 - f2).max()), force_max=float(np.abs(f1).max()))
    assert same["energy_rel_diff"] < 1e-10 and same["force_max_abs_diff"] < 1e-10 * same["force_max"]
    reps = max(50, a.steps // 10)
    groups = force_group_times(sims[names[2]], repeats=reps)
    groups += [g for g in force_group_times(sims[names[3]], repeats=reps) if "walls" in g["force"]]
    why = custom_force_costs(a.n_bp, reps)
    form_costs = wall_form_costs(a.n_bp, reps)
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
    members = [member_cost(a, form) for form in ("reference", "compiled")] if a.member_ns > 0 else []
    dt = sim.dt
    per_sample_steps = m["sample_ps"] / dt
    out = dict(date=time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), load_average_start=load0,
               load_average=os.getloadavg(), n_bp=a.n_bp, force_pN=a.force, turns=a.turns, dt_ps=dt,
               compiled_walls_available=wl.compiled_walls_available(),
               steps_per_measurement=a.steps, variants=variants, callback_path_variants=callback,
               wall_forms_same_energy=same, force_group_us=groups, custom_force_us_by_terms=why,
               wall_form_us=form_costs, observables_ms_per_sample=obs, default_sample_ps=m["sample_ps"],
               observables_share_at_default_sampling=sum(obs.values()) * 1e-3 /
               (sum(obs.values()) * 1e-3 + per_sample_steps / variants[names[3]]["steps_per_cpu_s"]),
               members=members)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps(out, indent=1) + "\n")
    print(f"{a.n_bp} bp at {a.force} pN, {a.turns} turns, {sim.rs.elastic} on {sim.platform_name}, dt {dt:.4f} ps, "
          f"load average {load0[0]:.1f} at the start, {out['load_average'][0]:.1f} at the end")
    for k, v in variants.items():
        print(f"  {k:48s} {v['steps_per_cpu_s']:7.0f} steps/CPU-s  {v['us_per_step']:6.1f} us/step  "
              f"{v['ns_per_cpu_day']:7.0f} ns/CPU-day")
    print("  Python-callback elastic path (elastic='fast'), by wall form: " + ", ".join(
        f"{k} {v['us_per_step']:.1f}" for k, v in callback.items()) + " us/step")
    print(f"  walls, Custom vs compiled: energy rel. diff {same['energy_rel_diff']:.1e}, "
          f"force max diff {same['force_max_abs_diff']:.1e} (max force {same['force_max']:.3g})")
    print("  each force alone (own force group, getState):")
    for g in groups:
        print(f"    {g['force']:52s} {g['type']:24s} {g['us_per_evaluation']:8.1f} us ({g['us_net']:6.1f} net)")
    print(f"  Custom forces alone on {3 * a.n_bp} particles (CPU platform, net us per evaluation):")
    for r in why:
        print(f"    {r['force']:24s} {r['terms']:6d} particles/bonds  {r['us_net']:7.1f} us")
    print("  the walls alone in each form (net us per evaluation):")
    for r in form_costs:
        print(f"    {r['platform']:10s} {r['form']:20s} {r['us_net']:7.1f} us")
    print("  observables per sample (ms): " + ", ".join(f"{k} {v:.2f}" for k, v in obs.items()))
    print(f"  observables' share of the CPU time at the default sampling ({m['sample_ps']:g} ps): "
          f"{100 * out['observables_share_at_default_sampling']:.1f} %")
    for r in members:
        print(f"  whole member, {r['form']:9s} walls: {r['production_ns']:g} ns + {r['equilibration_ns']:g} ns "
              f"eq., {r['n_steps']} steps, {r['wall_s']:.1f} s wall, {r['cpu_s']:.1f} s CPU "
              f"({r['us_per_step_cpu']:.1f} us CPU/step incl. observables)")


if __name__ == "__main__":
    main()
