"""Hand-made bad inputs for the misuse probe (in W = this folder/fx)."""
import gzip, shutil, subprocess, sys
from pathlib import Path
import numpy as np
W = Path(sys.argv[1]); W.mkdir(exist_ok=True)
S = Path("/work/shared/data/structures")
D = sys.argv[2]
lines = (S / "355D.pdb").read_text().splitlines()
atoms = [l for l in lines if l.startswith(("ATOM", "HETATM"))]
dna = [l for l in atoms if l[17:20].strip() in ("A", "C", "G", "T", "DA", "DC", "DG", "DT")]
(W / "ss.pdb").write_text("\n".join(l for l in dna if l[21] == "A") + "\nEND\n")
# RNA: T->U (drop C7/C5M), add O2' near C2'
rna = []
for l in dna:
    name = l[12:16].strip(); res = l[17:20].strip()
    if res in ("T", "DT") and name in ("C7", "C5M"):
        continue
    res2 = {"T": "U", "DT": "U", "DA": "A", "DC": "C", "DG": "G"}.get(res, res)
    l = l[:17] + f"{res2:>3s}" + l[20:]
    rna.append(l)
    if name == "C2'":
        x, y, z = float(l[30:38]), float(l[38:46]), float(l[46:54])
        rna.append(l[:12] + " O2'" + l[16:30] + f"{x+1.0:8.3f}{y+0.9:8.3f}{z+0.3:8.3f}" + l[54:])
(W / "rna.pdb").write_text("\n".join(rna) + "\nEND\n")
prot = [l for l in (S / "1KX5.pdb").read_text().splitlines() if l.startswith("ATOM") and l[17:20] in ("ALA", "ARG", "LYS", "GLY", "LEU", "SER", "THR", "VAL", "GLU", "ASP", "ILE", "PRO", "GLN", "ASN", "HIS", "TYR", "PHE", "MET", "CYS")]
(W / "protein.pdb").write_text("\n".join(prot) + "\nEND\n")
# multi-model: model 2 shifted; model 3 with fewer atoms
def shift(l, d):
    x, y, z = float(l[30:38]) + d, float(l[38:46]), float(l[46:54])
    return l[:30] + f"{x:8.3f}{y:8.3f}{z:8.3f}" + l[54:]
mm = ["MODEL        1"] + dna + ["ENDMDL", "MODEL        2"] + [shift(l, 0.3) for l in dna] + ["ENDMDL",
      "MODEL        3"] + dna[: len(dna) // 2] + ["ENDMDL", "END"]
(W / "multimodel.pdb").write_text("\n".join(mm) + "\n")
# altlocs: every atom of residue 3 of chain A duplicated as A/B with 0.5 occupancy, B shifted far
alt = []
for l in dna:
    if l[21] == "A" and l[22:26].strip() == "3":
        alt.append(l[:16] + "A" + l[17:54] + "  0.50" + l[60:])
        alt.append(shift(l[:16] + "B" + l[17:54] + "  0.50" + l[60:], 3.0))
    else:
        alt.append(l)
(W / "altloc.pdb").write_text("\n".join(alt) + "\nEND\n")
# mismatched strands: drop residues 5-7 of chain B
(W / "bulge.pdb").write_text("\n".join(l for l in dna if not (l[21] == "B" and l[22:26].strip() in ("17", "18", "19"))) + "\nEND\n")
(W / "crlf.pdb").write_bytes(("\r\n".join(dna) + "\r\nEND\r\n").encode())
(W / "nan.pdb").write_text("\n".join(l[:30] + "     nan" + l[38:] if i == 10 else l for i, l in enumerate(dna)) + "\nEND\n")
(W / "same_xyz.pdb").write_text("\n".join(l[:30] + f"{1.0:8.3f}{1.0:8.3f}{1.0:8.3f}" + l[54:] for l in dna) + "\nEND\n")
# one base pair: residue 1 of A and its partner (last of B)
resA = sorted({int(l[22:26]) for l in dna if l[21] == "A"}); resB = sorted({int(l[22:26]) for l in dna if l[21] == "B"})
(W / "onepair.pdb").write_text("\n".join(l for l in dna if (l[21] == "A" and int(l[22:26]) == resA[0]) or (l[21] == "B" and int(l[22:26]) == resB[-1])) + "\nEND\n")
(W / "twopair.pdb").write_text("\n".join(l for l in dna if (l[21] == "A" and int(l[22:26]) in resA[:2]) or (l[21] == "B" and int(l[22:26]) in resB[-2:])) + "\nEND\n")
(W / "empty.pdb").write_text("")
(W / "header_only.pdb").write_text("HEADER    NOTHING\nEND\n")
junk = np.random.default_rng(1).integers(0, 256, 3000, dtype=np.uint8).tobytes()
for n in ("binary.pdb", "binary.cif", "binary.toml", "binary.npz", "binary.dtraj", "binary.fa", "binary.txt", "binary.gz", "binary.xtc", "binary.dcd"):
    (W / n).write_bytes(junk)
txt = (S / "355D.pdb").read_text()
(W / "trunc.pdb").write_text(txt[: len(txt) // 2])
(W / "trunc_midline.pdb").write_text("\n".join(dna)[: len("\n".join(dna)) // 2 + 17])
shutil.copy(S / "355D.pdb", W / "pdb_named.cif")
shutil.copy(S / "355D.pdb", W / "pdb_named.npz")
shutil.copy(S / "355D.pdb", W / "pdb_named.txt")
shutil.copy(S / "355D.pdb", W / "pdb_named.toml")
(W / "gz.pdb.gz").write_bytes(gzip.compress((S / "355D.pdb").read_bytes()))
(W / "adir").mkdir(exist_ok=True)
(W / "adir.pdb").mkdir(exist_ok=True)
(W / "afile").write_text("x\n")
(W / "empty.fa").write_text("")
(W / "header.fa").write_text(">only\n")
(W / "empty.toml").write_text("")
(W / "ff_partial.toml").write_text('name = "x"\nkind = "uniform"\n')
subprocess.run([D, "build", "--sequence", "ACGTTGCAAC", "-o", str(W / "model.npz"), "--overwrite"], check=True)
shutil.copy(W / "model.npz", W / "npz_named.pdb")
subprocess.run([D, "lax-run", "ACGTTGCAAC", "-o", str(W / "run"), "--time", "0.002", "--frame-interval", "0.2", "--no-progress", "--seed", "3", "--overwrite"], check=True, stdout=subprocess.DEVNULL)
subprocess.run([D, "lax-run", "ACGTTGCAACACGTT", "-o", str(W / "run15"), "--time", "0.002", "--frame-interval", "0.2", "--no-progress", "--seed", "3", "--overwrite"], check=True, stdout=subprocess.DEVNULL)
(W / "empty.dtraj").write_bytes(b"")
t = (W / "run" / "trajectory.dtraj").read_bytes(); (W / "trunc.dtraj").write_bytes(t[: len(t) // 2])
np.savez(W / "foreign.npz", a=np.arange(3))
# ensemble specs
sp = W / "spec"; sp.mkdir(exist_ok=True)
specs = {
 "empty.toml": "",
 "nobase.toml": '[ensemble]\nname="x"\n',
 "nosource.toml": '[base]\ntime_ns=0.001\n',
 "axis_str.toml": '[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\n[axes]\nforce_pN=["a","b"]\n',
 "axis_dup.toml": '[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\n[axes]\nforce_pN=[1,1]\n',
 "axis_nan.toml": '[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\n[axes]\nforce_pN=[1,nan]\n',
 "axis_neg_force.toml": '[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\n[axes]\nforce_pN=[-1,1]\n',
 "linspace_huge.toml": '[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\n[axes]\nforce_pN={linspace=[0,1,1000000000]}\n',
 "cross_huge.toml": '[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\n[axes]\nforce_pN={linspace=[0,1,2000]}\ntemperature_K={linspace=[290,310,2000]}\n',
 "replicas_huge.toml": '[ensemble]\nreplicas=1000000000\n[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\n',
 "replicas_zero.toml": '[ensemble]\nreplicas=0\n[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\n',
 "blocks_zero.toml": '[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\n[analysis]\nblocks=0\n',
 "blocks_one.toml": '[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\n[analysis]\nblocks=1\n',
 "discard_all.toml": '[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\n[analysis]\ndiscard_ns=5\n',
 "time_huge.toml": '[base]\nsource="ACGTACGTAC"\ntime_ns=1e300\n',
 "protocol_os.toml": '[ensemble]\nprotocol="os:system"\n[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\n',
 "protocol_missing.toml": '[ensemble]\nprotocol="nope.nothing:x"\n[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\n',
 "protocol_bad.toml": '[ensemble]\nprotocol="json"\n[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\n',
 "source_missing_file.toml": '[base]\nsource="nope.pdb"\ntime_ns=0.001\n',
 "source_dir.toml": '[base]\nsource="../adir.pdb"\ntime_ns=0.001\n',
 "source_binary.toml": '[base]\nsource="../binary.pdb"\ntime_ns=0.001\n',
 "source_ss.toml": '[base]\nsource="../ss.pdb"\ntime_ns=0.001\n',
 "source_protein.toml": '[base]\nsource="../protein.pdb"\ntime_ns=0.001\n',
 "source_zero.toml": '[base]\nsource="0"\ntime_ns=0.001\n',
 "source_one.toml": '[base]\nsource="1"\ntime_ns=0.001\n',
 "source_empty.toml": '[base]\nsource=""\ntime_ns=0.001\n',
 "source_num.toml": '[base]\nsource=1e3\ntime_ns=0.001\n',
 "delta_lk_open.toml": '[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\ndelta_lk=2\n',
 "torque_free.toml": '[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\ntorque_pN_nm=10\n',
 "ring_pull.toml": '[base]\nsource="ACGTACGTACGTACGTACGTACGTACGTAC"\ntime_ns=0.001\nring=true\nforce_pN=2\n',
 "ring_circular.toml": '[base]\nsource="ACGTACGTACGTACGTACGTACGTACGTAC"\ntime_ns=0.001\nring=true\ncircular=true\n',
 "platform_bad.toml": '[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\nplatform="Foo"\n',
 "ff_missing.toml": '[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\nforcefield="nope"\n',
 "temp_huge.toml": '[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\ntemperature_K=1e9\n',
 "turns_huge.toml": '[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\nrotation_clamp_kJ_mol=100\nturns=1e9\nforce_pN=1\nclamp_first=true\n',
 "frame_gt_time.toml": '[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\nframe_interval_ps=100\n',
 "dt_huge.toml": '[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\ndt_ps=5\n',
 "seed_neg.toml": '[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\nseed=-5\n',
 "seed_huge.toml": '[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\nseed=99999999999999\n',
 "unknown_table.toml": '[base]\nsource="ACGTACGTAC"\n[foo]\nx=1\n',
 "nested.toml": '[base]\nsource="ACGTACGTAC"\n[base.sub]\nx=1\n',
 "zip_unknown.toml": '[ensemble]\nzip=[["force_pN","nope"]]\n[base]\nsource="ACGTACGTAC"\n[axes]\nforce_pN=[1,2]\n',
 "logspace_neg.toml": '[base]\nsource="ACGTACGTAC"\n[axes]\nforce_pN={logspace=[-1,1,3]}\n',
 "fasta_binary.toml": '[base]\ntime_ns=0.001\n[axes]\nfasta="../binary.fa"\n',
 "fasta_dir.toml": '[base]\ntime_ns=0.001\n[axes]\nfasta="../adir"\n',
 "fasta_dup.toml": '[base]\ntime_ns=0.001\n[axes]\nfasta="../dup.fa"\n',
 "salt_axis_zero.toml": '[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\n[axes]\nsalt_M=[0.1, 0]\n',
 "start_eq_ring.toml": '[base]\nsource="ACGTACGTACGTACGTACGTACGTACGTAC"\ntime_ns=0.001\nring=true\nstart="equilibrium"\n',
 "name_slash.toml": '[ensemble]\nname="../../etc"\n[base]\nsource="ACGTACGTAC"\ntime_ns=0.001\n',
}
for n, t in specs.items():
    (sp / n).write_text(t)
(sp / "binary.toml").write_bytes(junk)
(W / "dup.fa").write_text(">a\nACGTACGTAC\n>a\nACGTACGTAC\n")
(W / "pairs_empty.txt").write_text("")
(W / "pairs_bad.txt").write_text("A:1 B:999\n")
(W / "pairs_dup.txt").write_text("A:1 B:24\nA:1 B:24\n")
(W / "pairs_self.txt").write_text("A:1 A:1\n")
# round 7: a project folder (no dnarod output) and a finished validation report
(W / "proj" / ".git").mkdir(parents=True, exist_ok=True)
(W / "proj" / "notes.txt").write_text("notes\n")
(W / "rep").mkdir(exist_ok=True)
(W / "rep" / "results.json").write_text('{"checks": {}}\n')
(W / "rep" / "report.md").write_text("# dnarod validation report\n")
print("fixtures in", W)
