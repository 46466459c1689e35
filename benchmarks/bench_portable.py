"""Benchmark: how fast the portable elastic force (CustomCompoundBondForce) compiles, per platform.

For three stiffness structures -- ``dna-default`` (diagonal + twist-stretch coupling, 7 of 21
entries), ``full`` (a different random SPD 6x6 matrix with all 21 entries and random intrinsic
strains on every step: sequence-dependent) and ``circular`` (dna-default closed by a screw, two
forces, the closing one with the image rotation) -- on 100 nodes, each measured in a fresh process:

* OpenMM Context creation (CPU seconds of the whole process and wall seconds) on Reference, CPU
  and OpenCL (if present; pocl's kernel cache on disk makes repeated runs faster, so on OpenCL
  the first and second creation in the process are both reported);
* the energy's relative deviation from :func:`dnarod.energy.energy` at a perturbed pose;
* Lepton operation counts (``benchmarks/lepton/lepton_ops.cpp``, built with g++ against the
  headers and library shipped in the openmm wheel, if both are found): nodes of the energy tree
  and of the 18 coordinate derivatives after Lepton's ``optimize()``, as OpenMM's Reference and
  CPU kernels build them.

``--baseline REV`` also measures the expression of ``dnarod/openmm/forces.py`` at git revision
REV (e.g. the one before the Cholesky form).

Usage: ``python benchmarks/bench_portable.py [--platforms Reference,CPU,OpenCL] [--baseline REV] [--json OUT]``.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CASES = ("dna-default", "full", "circular", "full-circular", "olson1998", "olson1998-circular")


def _forces_module(rev):
    """dnarod.openmm.forces as of ``rev`` (None: the working tree)."""
    if rev is None:
        from dnarod.openmm import forces

        return forces
    src = subprocess.run(["git", "-C", str(ROOT), "show", f"{rev}:dnarod/openmm/forces.py"], capture_output=True,
                         text=True, check=True).stdout
    d = tempfile.mkdtemp()
    path = Path(d) / "forces_baseline.py"
    path.write_text(src.replace("from ..", "from dnarod.").replace("from .particles", "from dnarod.openmm.particles"))
    spec = importlib.util.spec_from_file_location("forces_baseline", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _model(case):
    """100 nodes: ``dna-default`` (open), ``full`` (random full K and intrinsic strains per step, open),
    ``circular`` (dna-default closed by its helical screw), ``full-circular`` (``full`` closed by a general
    screw), ``olson1998`` and ``olson1998-circular`` (sequence-dependent full K of the bundled set)."""
    from dnarod.forcefield import load_forcefield
    from dnarod.model import RodModel
    from dnarod.parameters import StepParameters
    from dnarod.rotations import cayley, rotation_about_axis
    from dnarod.strains import Closure

    circular = case.endswith("circular")
    ff = load_forcefield("olson1998" if case.startswith("olson") else "dna-default")
    rng = np.random.default_rng(7)
    seq = "".join(rng.choice(list("ACGT"), 100))
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


def single(case, plat, rev):
    import openmm

    from dnarod.energy import energy
    from dnarod.openmm import particles as P
    from dnarod.openmm.platforms import platform_properties

    forces = _forces_module(rev)
    m = _model(case)
    r = P.triangle_radius(m.mass, m.inertia)
    out = dict(case=case, platform=plat, revision=rev or "working tree")
    times = []
    for _ in range(2 if plat == "OpenCL" else 1):
        system = openmm.System()
        for mass in np.repeat(m.mass / 3, 3):
            system.addParticle(mass)
        for f in forces.elastic_compound_forces(m, r):
            system.addForce(f)
        c0, w0 = time.process_time(), time.perf_counter()
        ctx = openmm.Context(system, openmm.VerletIntegrator(0.001), openmm.Platform.getPlatformByName(plat),
                             platform_properties(plat))
        ctx.setPositions(P.particle_positions(m.positions, m.frames, r))
        E = ctx.getState(getEnergy=True, getForces=True).getPotentialEnergy()._value
        times.append((time.process_time() - c0, time.perf_counter() - w0))
        del ctx
    out["context_cpu_s"], out["context_wall_s"] = times[0]
    out["second_context_cpu_s"], out["second_context_wall_s"] = times[-1]
    E0 = energy(m.positions, m.frames, m.params, m.ds, m.closure)
    out["energy_rel_error"] = abs(E - E0) / abs(E0)
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


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--platforms", default="Reference,CPU,OpenCL")
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--baseline", default=None, help="git revision whose expression is measured as 'before'")
    ap.add_argument("--baseline-platforms", default="Reference", help="platforms for the baseline (slow to compile)")
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "results" / "bench_portable.json"))
    ap.add_argument("--single", nargs=3, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.single is not None:
        case, plat, rev = args.single
        print(json.dumps(single(case, plat, None if rev == "-" else rev)))
        return
    import openmm

    have = {openmm.Platform.getPlatform(i).getName() for i in range(openmm.Platform.getNumPlatforms())}
    plats = [p for p in args.platforms.split(",") if p in have]
    revs = [None] + ([args.baseline] if args.baseline else [])
    tool = _lepton_tool()
    results = []
    counted = {}
    for rev in revs:
        for case in args.cases.split(","):
            for plat in (plats if rev is None else [p for p in args.baseline_platforms.split(",") if p in have]):
                p = subprocess.run([sys.executable, __file__, "--single", case, plat, rev or "-"], capture_output=True,
                                   text=True, timeout=3600)
                if p.returncode != 0:
                    results.append(dict(case=case, platform=plat, revision=rev or "working tree",
                                        error=(p.stderr.strip().splitlines() or ["failed"])[-1]))
                    continue
                r = json.loads(p.stdout.strip().splitlines()[-1])
                if tool is not None:
                    counts = []
                    for expr in r["expressions"]:
                        if expr not in counted:
                            q = subprocess.run([str(tool), "6"], input=expr, capture_output=True, text=True)
                            counted[expr] = json.loads(q.stdout)
                        counts.append(counted[expr])
                    r["lepton"] = counts
                results.append(r)
                print(f"measured {case} on {plat} ({rev or 'working tree'})", file=sys.stderr)
    print("portable force (100 nodes): Context creation CPU s (wall s), 2nd creation CPU s; energy vs dnarod.energy; "
          "Lepton nodes energy / derivatives (per force)")
    for r in results:
        if "error" in r:
            print(f"{r['revision'][:12]:>12} {r['case']:>11} {r['platform']:>9} error: {r['error']}")
            continue
        lep = "; ".join(f"{c['energy_tree_nodes']}/{c['derivative_tree_nodes']}" for c in r.get("lepton", []))
        print(f"{r['revision'][:12]:>12} {r['case']:>11} {r['platform']:>9} {r['context_cpu_s']:6.2f} "
              f"({r['context_wall_s']:6.2f}) {r['second_context_cpu_s']:6.2f}  rel.err {r['energy_rel_error']:.1e}  "
              f"{lep}")
    out = dict(benchmark="bench_portable", machine=platform.platform(), cpu_count=os.cpu_count(),
               date=time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), results=results,
               target="Context creation < 2 s on every platform for any stiffness")
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(out, indent=2))
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
