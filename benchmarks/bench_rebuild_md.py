"""Benchmark: all-atom rebuild of a structure's nodes, then Amber14 createSystem and MD stability.

Reads the structure (default the 147-bp nucleosome 1KX5), builds its nodes
(``model_from_structure``), rebuilds the all-atom duplex
(:func:`dnarod.structure.allatom.rebuild_allatom`, timed: wall and CPU), writes the PDB, loads
it back with OpenMM, builds ``ForceField("amber14-all.xml", "implicit/obc2.xml").createSystem``
(H bonds constrained; the CustomGBForce replaced by the native GBSAOBCForce with the same
parameters; non-periodic cut-off ``--cutoff`` nm) and runs ``--steps`` steps of Langevin MD
(300 K, 1/ps, 2 fs, CPU platform), recording per ps the potential energy, the heavy-atom RMSD
from the start and the O3'-P range.

Usage: ``python benchmarks/bench_rebuild_md.py [--structure 1KX5] [--steps 5000] [--cutoff 2.0]
[--out DIR] [--json OUT] [--pdb FILE]``; ``--pdb`` skips the rebuild and runs the MD on a duplex
already rebuilt (e.g. ``bench_rebuild.py --keep DIR``), re-measuring its bond geometry. The machine is shared: compare
figures from the same run only.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--structure", default="1KX5")
    ap.add_argument("--steps", type=int, default=5000)
    ap.add_argument("--cutoff", type=float, default=2.0, help="nm, non-periodic cut-off for the MD")
    ap.add_argument("--out", default=str(ROOT / "runs"), help="where the rebuilt PDB goes")
    ap.add_argument("--json", default=None)
    ap.add_argument("--pdb", default=None, help="an already rebuilt PDB: skip the rebuild")
    a = ap.parse_args()
    import openmm
    import openmm.app as app
    import openmm.unit as u

    from dnarod.structure import model_from_structure
    from dnarod.structure.allatom import amber_md_simulation, rebuild_allatom

    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    if a.pdb is None:
        m = model_from_structure(ROOT / "data" / "structures" / f"{a.structure}.pdb")
        t0, c0 = time.perf_counter(), resource.getrusage(resource.RUSAGE_SELF).ru_utime
        res = rebuild_allatom(m.frames, m.positions, m.sequence, np.array(m.metadata["bp_params"]),
                              m.metadata["sequence2"])
        wall, cpu = time.perf_counter() - t0, resource.getrusage(resource.RUSAGE_SELF).ru_utime - c0
        print(f"{a.structure}: {m.n_nodes} bp, rebuild {wall:.1f} s wall, {cpu:.1f} s CPU "
              f"({wall / m.n_nodes:.2f} / {cpu / m.n_nodes:.2f} s per bp)", flush=True)
        for line in res.report.summary():
            print("  " + line, flush=True)
        pdb_path = out / f"{a.structure}_rebuilt.pdb"
        res.write(pdb_path)
        rep = {k: (list(v) if isinstance(v, tuple) else v) for k, v in res.report.__dict__.items()}
        rep.update(structure=a.structure, n_bp=m.n_nodes, atoms=res.topology.getNumAtoms(), wall_s=wall, cpu_s=cpu,
                   load_average_after_rebuild=os.getloadavg())
    else:
        pdb_path = Path(a.pdb)
        rep = {"structure": a.structure, "rebuilt_pdb": str(pdb_path)}
    pdb = app.PDBFile(str(pdb_path))
    ff = app.ForceField("amber14-all.xml", "implicit/obc2.xml")
    system = ff.createSystem(pdb.topology, nonbondedMethod=app.CutoffNonPeriodic,
                             nonbondedCutoff=a.cutoff * u.nanometer, constraints=app.HBonds)
    print(f"createSystem(amber14-all.xml + implicit/obc2.xml): {system.getNumParticles()} particles", flush=True)
    hb0 = [f for f in system.getForces() if isinstance(f, openmm.HarmonicBondForce)][0]
    xyz = np.array(pdb.positions.value_in_unit(u.nanometer))
    dev = [abs(np.linalg.norm(xyz[i] - xyz[j]) - r0.value_in_unit(u.nanometer))
           for i, j, r0, _ in (hb0.getBondParameters(k) for k in range(hb0.getNumBonds()))]
    rep.update(file_max_bond_dev_A=10 * float(np.max(dev)) if dev else float("nan"),
               file_bonds_checked=len(dev), createsystem_particles=system.getNumParticles(),
               note_constraints="HBonds constrained: X-H bonds are constraints, not HarmonicBondForce terms")
    print(f"bonds in the file (amber14-all, heavy-atom bonds): largest deviation {rep['file_max_bond_dev_A']:.4f} A",
          flush=True)
    sim = amber_md_simulation(pdb, a.cutoff)  # the MD system (native OBC2), as the tests run it
    system = sim.system
    x0 = np.array(pdb.positions.value_in_unit(u.nanometer))
    heavy = np.array([at.element.symbol != "H" for at in pdb.topology.atoms()])
    names = [at.name for at in pdb.topology.atoms()]
    hb = [f for f in system.getForces() if isinstance(f, openmm.HarmonicBondForce)][0]
    o3p = [(i, j) for i, j, *_ in (hb.getBondParameters(k) for k in range(hb.getNumBonds()))
           if {names[i], names[j]} == {"O3'", "P"}]
    t1, c1 = time.perf_counter(), resource.getrusage(resource.RUSAGE_SELF).ru_utime
    traj = []
    for block in range(a.steps // 500):
        sim.step(500)
        st = sim.context.getState(getPositions=True, getEnergy=True)
        x = st.getPositions(asNumpy=True).value_in_unit(u.nanometer)
        d = [np.linalg.norm(x[i] - x[j]) for i, j in o3p]
        traj.append({"ps": block + 1, "energy_kJ_mol": st.getPotentialEnergy().value_in_unit(u.kilojoule_per_mole),
                     "heavy_rmsd_A": 10 * float(np.sqrt(np.mean(np.sum((x - x0)[heavy] ** 2, axis=1)))),
                     "o3p_min_A": 10 * min(d), "o3p_max_A": 10 * max(d)})
        print(json.dumps(traj[-1]), flush=True)
    rep.update(md=traj, md_wall_s=time.perf_counter() - t1,
               md_cpu_s=resource.getrusage(resource.RUSAGE_SELF).ru_utime - c1,
               md_conditions=f"Langevin middle 300 K, 1/ps, 2 fs, HBonds constrained, amber14-all + OBC2 (native "
                             f"GBSAOBCForce), CutoffNonPeriodic {a.cutoff} nm, CPU platform",
               machine=platform.platform(), openmm=openmm.__version__)
    path = Path(a.json or ROOT / "benchmarks" / "results" / f"bench_rebuild_md_{a.structure}.json")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(rep, indent=1, default=float))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
