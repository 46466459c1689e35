"""Benchmark: how fast the portable elastic force (CustomCompoundBondForce) compiles, per platform.

For the stiffness structures ``dna-default`` (diagonal + twist-stretch coupling, 7 of 21
entries), ``full`` (a different random SPD 6x6 matrix with all 21 entries and random intrinsic
strains on every step: sequence-dependent) and ``olson1998`` (the bundled sequence-dependent
21-entry set), open and circular (``circular``: dna-default closed by its helical screw;
``full-circular``: ``full`` closed by a general screw; ``olson1998-circular``; ``olson1998-ring``: a
plain planar ring, identity closure, supercoiled by Delta Lk = +2), on 100 and
1000 nodes (``--nodes``), each measured in a fresh process:

* OpenMM Context creation (CPU seconds of the whole process and wall seconds) on Reference, CPU
  and OpenCL (if present; pocl's kernel cache on disk makes repeated runs faster, so on OpenCL
  the first and second creation in the process are both reported);
* the energy's relative deviation from :func:`dnarod.core.energy.energy` at a perturbed pose;
* Lepton operation counts (``benchmarks/lepton/lepton_ops.cpp``, built with g++ against the
  headers and library shipped in the openmm wheel, if both are found): nodes of the energy tree
  and of the 18 coordinate derivatives after Lepton's ``optimize()``, as OpenMM's Reference and
  CPU kernels build them.

``--baseline REV`` also measures the portable force of ``dnarod/openmm/forces.py`` at git revision
REV (e.g. the one before the closing step moved onto node 0's image particles; revisions without
``add_closure_image`` write the closing step's screw into its own expressions).

Usage: ``python benchmarks/bench_portable.py [--platforms Reference,CPU,OpenCL] [--nodes 100,1000]
[--baseline REV] [--json OUT]``.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import _harness as H

ROOT = Path(__file__).resolve().parents[1]
CASES = ("dna-default", "full", "circular", "full-circular", "olson1998", "olson1998-circular", "olson1998-ring")


def _forces_module(rev):
    """dnarod.engines.openmm.forces as of ``rev`` (None: the working tree)."""
    if rev is None:
        from dnarod.engines.openmm import forces

        return forces
    src = subprocess.run(["git", "-C", str(ROOT), "show", f"{rev}:dnarod/openmm/forces.py"], capture_output=True,
                         text=True, check=True).stdout
    d = tempfile.mkdtemp()
    path = Path(d) / "forces_baseline.py"
    path.write_text(src.replace("from ..", "from dnarod.").replace("from .particles",
                                                                   "from dnarod.engines.openmm.particles"))
    spec = importlib.util.spec_from_file_location("forces_baseline", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _model(case, n_nodes=100):
    """``n_nodes`` nodes: ``dna-default`` (open), ``full`` (random full K and intrinsic strains per step, open),
    ``circular`` (dna-default closed by its helical screw), ``full-circular`` (``full`` closed by a general
    screw), ``olson1998`` and ``olson1998-circular`` (sequence-dependent full K of the bundled set),
    ``olson1998-ring`` (a plain ring, identity closure, Delta Lk = +2)."""
    from dnarod.core.forcefield import load_forcefield
    from dnarod.core.model import RodModel
    from dnarod.core.parameters import StepParameters
    from dnarod.core.rotations import cayley, rotation_about_axis
    from dnarod.core.strains import Closure

    circular = case.endswith("circular")
    ff = load_forcefield("olson1998" if case.startswith("olson") else "dna-default")
    rng = np.random.default_rng(7)
    seq = "".join(rng.choice(list("ACGT"), n_nodes))
    if case.endswith("ring"):
        m = ff.ring(seq, delta_linking_number=2)
    else:
        m = ff.model_from_sequence(seq, circular=circular)
    params, closure = m.params, m.closure
    if case.startswith("full"):
        A = rng.normal(size=(m.n_steps, 6, 6))
        K = np.einsum("kij,klj->kil", A, A) * 20 + np.eye(6) * 50
        params = StepParameters(K, m.params.intrinsic + 0.1 * rng.normal(size=m.params.intrinsic.shape))
    if case == "full-circular":
        axis = np.array([0.3, 0.2, 1.0]) / np.linalg.norm([0.3, 0.2, 1.0])
        closure = Closure(rotation_about_axis(axis, 0.7), np.array([0.1, -0.2, 3.3]))
    pos = m.positions + 0.03 * rng.normal(size=m.positions.shape)
    frm = cayley(0.05 * rng.normal(size=(m.n_nodes, 3))) @ m.frames
    return RodModel(pos, frm, params, m.ds, m.mass, m.inertia, closure=closure)


def _context_time(system, plat, positions=None):
    """CPU and wall seconds to create an OpenMM Context (LangevinMiddle) and evaluate energy and forces once.

    CPU time is that of all threads of this process plus any child processes it waited for (pocl may run
    the linker as a separate process)."""
    import openmm

    from dnarod.engines.openmm.platforms import platform_properties

    c0, w0 = H.cpu_seconds(), time.perf_counter()
    ctx = openmm.Context(system, openmm.LangevinMiddleIntegrator(300.0, 1.0, 0.001),
                         openmm.Platform.getPlatformByName(plat), platform_properties(plat))
    if positions is not None:
        ctx.setPositions(positions)
    state = ctx.getState(getEnergy=True, getForces=True)
    out = (H.cpu_seconds() - c0, time.perf_counter() - w0)
    del ctx
    return out, state


def trivial(plat):
    """OpenMM's own cost: two particles, one HarmonicBondForce, LangevinMiddleIntegrator (two Contexts)."""
    import openmm

    out = dict(case="trivial (HarmonicBondForce)", platform=plat)
    times = []
    for _ in range(2):
        system = openmm.System()
        system.addParticle(1.0)
        system.addParticle(1.0)
        f = openmm.HarmonicBondForce()
        f.addBond(0, 1, 0.1, 1000.0)
        system.addForce(f)
        t, _ = _context_time(system, plat, [openmm.Vec3(0, 0, 0), openmm.Vec3(0.11, 0, 0)])
        times.append(t)
    out["context_cpu_s"], out["context_wall_s"] = times[0]
    out["second_context_cpu_s"], out["second_context_wall_s"] = times[1]
    return out


def single(case, plat, rev, n_nodes=100):
    import openmm

    from dnarod.core.energy import energy
    from dnarod.engines.openmm import particles as P

    if case == "trivial":
        return trivial(plat)
    forces = _forces_module(rev)
    m = _model(case, n_nodes)
    r = P.triangle_radius(m.mass, m.inertia)
    out = dict(case=case, platform=plat, revision=rev or "working tree", n_nodes=n_nodes)
    times = []
    for _ in range(2 if plat == "OpenCL" else 1):
        system = openmm.System()
        for mass in np.repeat(m.mass / 3, 3):
            system.addParticle(mass)
        x = P.particle_positions(m.positions, m.frames, r)
        kw = {}
        if m.closure is not None and hasattr(forces, "add_closure_image"):  # the closing step on node 0's image
            kw["image"] = forces.add_closure_image(system, m)
            if kw["image"]:  # 0: a plain ring's node 0 is its own image
                x = np.vstack([x, P.closure_image_positions(x, m.closure)])
        for f in forces.elastic_compound_forces(m, r, **kw):
            system.addForce(f)
        t, state = _context_time(system, plat, x)
        times.append(t)
    E = state.getPotentialEnergy()._value
    out["context_cpu_s"], out["context_wall_s"] = times[0]
    out["second_context_cpu_s"], out["second_context_wall_s"] = times[-1]
    E0 = energy(m.positions, m.frames, m.params, m.ds, m.closure)
    out["energy_rel_error"] = abs(E - E0) / abs(E0)
    out["n_forces"] = system.getNumForces()
    out["expressions"] = [system.getForce(i).getEnergyFunction() for i in range(system.getNumForces())]
    return out


def _lepton_tool():
    """Path of the compiled Lepton counter, or None (no g++ or no OpenMM headers)."""
    import openmm

    base = Path(openmm.__file__).resolve().parents[1] / "OpenMM.libs"
    if not (base / "include" / "lepton" / "Parser.h").exists():
        return None
    exe = Path(tempfile.gettempdir()) / "dnarod_lepton_ops"
    src = ROOT / "benchmarks" / "lepton" / "lepton_ops.cpp"
    if not exe.exists() or exe.stat().st_mtime < src.stat().st_mtime:
        p = subprocess.run(["g++", "-O2", "-std=c++11", str(src), f"-I{base / 'include'}", f"-L{base / 'lib'}",
                            "-lOpenMM", f"-Wl,-rpath,{base / 'lib'}", "-o", str(exe)], capture_output=True, text=True)
        if p.returncode != 0:
            return None
    return exe


def _run(case, plat, rev, n_nodes, env=None):
    p = subprocess.run([sys.executable, __file__, "--single", case, plat, rev or "-", str(n_nodes)],
                       capture_output=True, text=True, timeout=3600, env=env)
    if p.returncode != 0:
        return dict(case=case, platform=plat, revision=rev or "working tree", n_nodes=n_nodes,
                    error=(p.stderr.strip().splitlines() or ["failed"])[-1])
    return json.loads(p.stdout.strip().splitlines()[-1])


def _run_batch(cases, plat, rev, n_nodes):
    """All ``cases`` in one process (``--batch``), the trivial System first (it pays the platform's start-up).
    OpenCL: a fresh, empty pocl cache for the process; each case's first Context is reported as ``cold``
    (OpenMM's own kernels are then already cached by the trivial System, so this is what dnarod's forces add
    cold), its second as warm."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, POCL_CACHE_DIR=cache)
        p = subprocess.run([sys.executable, __file__, "--single", "+".join(["trivial"] + cases), plat, rev or "-",
                            str(n_nodes)], capture_output=True, text=True, timeout=7200, env=env)
    out = [json.loads(line) for line in p.stdout.splitlines() if line.startswith("{")]
    if p.returncode != 0:
        out.append(dict(case="+".join(cases), platform=plat, revision=rev or "working tree", n_nodes=n_nodes,
                        error=(p.stderr.strip().splitlines() or ["failed"])[-1]))
    for r in out:
        r["batch"] = True
        if plat == "OpenCL" and "second_context_cpu_s" in r:
            r["cold_context_cpu_s"], r["cold_context_wall_s"] = r["context_cpu_s"], r["context_wall_s"]
            r["context_cpu_s"], r["context_wall_s"] = r["second_context_cpu_s"], r["second_context_wall_s"]
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--platforms", default="Reference,CPU,OpenCL")
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--baseline", default=None, help="git revision whose expression is measured as 'before'")
    ap.add_argument("--baseline-platforms", default="Reference", help="platforms for the baseline (slow to compile)")
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "results" / "bench_portable.json"))
    ap.add_argument("--nodes", default="100,1000", help="chain lengths (comma-separated)")
    ap.add_argument("--batch", action="store_true",
                    help="one process per (nodes, revision, platform) for all cases (much less start-up work on a "
                         "loaded machine); on OpenCL each case's first Context is the cold one (see _run_batch)")
    ap.add_argument("--baseline-cases", default=None, help="cases measured at the baseline (default: all)")
    ap.add_argument("--baseline-nodes", default=None, help="chain lengths measured at the baseline (default: all)")
    ap.add_argument("--single", nargs=4, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.single is not None:
        cases, plat, rev, n_nodes = args.single
        for case in cases.split("+"):
            print(json.dumps(single(case, plat, None if rev == "-" else rev, int(n_nodes))), flush=True)
        return
    import openmm

    have = {openmm.Platform.getPlatform(i).getName() for i in range(openmm.Platform.getNumPlatforms())}
    plats = [p for p in args.platforms.split(",") if p in have]
    revs = [None] + ([args.baseline] if args.baseline else [])
    tool = _lepton_tool()
    results = []
    counted = {}
    load = [os.getloadavg()]
    bcases = args.cases.split(",") if args.baseline_cases is None else args.baseline_cases.split(",")
    bnodes = args.nodes if args.baseline_nodes is None else args.baseline_nodes
    if args.batch:
        for n_nodes in map(int, args.nodes.split(",")):
            for rev in revs:
                if rev is not None and str(n_nodes) not in bnodes.split(","):
                    continue
                for plat in (plats if rev is None else [p for p in args.baseline_platforms.split(",") if p in have]):
                    rs = _run_batch(args.cases.split(",") if rev is None else bcases, plat, rev, n_nodes)
                    if n_nodes != int(args.nodes.split(",")[0]) or rev is not None:
                        rs = [r for r in rs if not r["case"].startswith("trivial")]
                    results.extend(rs)
                    print(f"measured {n_nodes} nodes on {plat} ({rev or 'working tree'}), load "
                          f"{os.getloadavg()[0]:.1f}", file=sys.stderr)
                    H.write_results(args.json, "bench_portable", partial=True, openmm=openmm.__version__,
                                    load_average_start_now=[load[0], os.getloadavg()],
                                    results=[{k: v for k, v in r.items() if k != "expressions"} for r in results])
    # the working tree and the baseline alternate case by case, so before and after see the same load
    jobs = [] if args.batch else [(n_nodes, case, rev) for n_nodes in map(int, args.nodes.split(","))
            for case in ["trivial"] + args.cases.split(",") for rev in revs
            if not (case == "trivial" and (rev is not None or n_nodes != int(args.nodes.split(",")[0])))
            and (rev is None or (case in bcases and str(n_nodes) in bnodes.split(",")))]
    for n_nodes, case, rev in jobs:
        for plat in (plats if rev is None else [p for p in args.baseline_platforms.split(",") if p in have]):
            if plat == "OpenCL":
                # cold: a fresh, empty pocl kernel cache (first Context compiles every kernel); warm: a new
                # process on the cache the cold run filled (what every later run sees)
                with tempfile.TemporaryDirectory() as cache:
                    env = dict(os.environ, POCL_CACHE_DIR=cache)
                    cold = _run(case, plat, rev, n_nodes, env)
                    r = _run(case, plat, rev, n_nodes, env)
                if "error" not in r and "error" not in cold:
                    r["cold_context_cpu_s"], r["cold_context_wall_s"] = cold["context_cpu_s"], cold["context_wall_s"]
            else:
                r = _run(case, plat, rev, n_nodes)
            results.append(r)
            print(f"measured {case} ({n_nodes} nodes) on {plat} ({rev or 'working tree'}), "
                  f"load {os.getloadavg()[0]:.1f}", file=sys.stderr)
    load.append(os.getloadavg())
    for r in results:  # after the timings (the counter's own work does not load the measured processes)
        if tool is not None and "expressions" in r:
            counts = []
            for expr in r["expressions"]:
                if expr not in counted:
                    q = subprocess.run([str(tool), "6"], input=expr, capture_output=True, text=True)
                    counted[expr] = json.loads(q.stdout)
                counts.append(counted[expr])
            r["lepton"] = counts
            r["lepton_total"] = {k: sum(c[k] for c in counts) for k in ("energy_tree_nodes",
                                                                        "derivative_tree_nodes")}
        r.pop("expressions", None)
    print("portable force: Context creation (LangevinMiddle) CPU s (wall s); OpenCL: warm (pocl cache filled), "
          "cold (empty cache); energy vs dnarod.core.energy; Lepton tree nodes energy / 18 derivatives (all forces)")
    for r in results:
        if "error" in r:
            print(f"{r['revision'][:12]:>12} {r.get('n_nodes', ''):>5} {r['case']:>18} {r['platform']:>9} "
                  f"error: {r['error']}")
            continue
        lep = r.get("lepton_total")
        lep = f"{lep['energy_tree_nodes']}/{lep['derivative_tree_nodes']}" if lep else ""
        cold = (f" cold {r['cold_context_cpu_s']:6.2f} ({r['cold_context_wall_s']:6.2f})"
                if "cold_context_cpu_s" in r else "")
        err = f"rel.err {r['energy_rel_error']:.1e}" if "energy_rel_error" in r else ""
        print(f"{r.get('revision', '')[:12]:>12} {r.get('n_nodes', ''):>5} {r['case']:>18} {r['platform']:>9} "
              f"{r['context_cpu_s']:6.2f} ({r['context_wall_s']:6.2f}){cold} forces {r.get('n_forces', 1):>2} "
              f"{err} {lep}")
    H.write_results(args.json, "bench_portable", load_average_start_end=load, openmm=openmm.__version__,
                    results=results, target="Context creation < 2 s on every platform for any stiffness")

if __name__ == "__main__":
    main()
