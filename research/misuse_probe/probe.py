"""Misuse probe: every command and option fed bad values and held-out inputs (535 cases), each in a fresh click
test runner; flags tracebacks, exit statuses other than 0/2, more than one stderr line, stdout before a refusal,
files changed, and lists every accepted case for reading.

    python research/misuse_probe/make_fixtures.py /tmp/mp/fx .venv/bin/dnarod    # bad files, a short run, specs
    python research/misuse_probe/probe.py /tmp/mp/fx x "" /tmp/mp/probe.json > /tmp/mp/probe.log

Cases that would start 10^5 dask workers, allocate 10^9-member axes or write a run into / are left out (they
were read from the code; tests/test_misuse_cli_inputs.py holds their refusals). Needs the structures in
/work/shared/data/structures. Results of rounds 6 and 7: docs/misuse.md.
"""
import json, os
from click.testing import CliRunner
from dnarod.cli.main import main
import sys, time
from pathlib import Path
W = Path(sys.argv[1]); D = sys.argv[2]; only = sys.argv[3] if len(sys.argv) > 3 else None
S = "/work/shared/data/structures"
SEQ = "ACGTTGCAAC"; SEQ40 = "ACGT" * 10
Q = ["--time", "0.002", "--no-progress", "--seed", "3", "--frame-interval", "0.2", "--no-export"]
L = ["--engine", "lax"]
P = ["--source", "40", "--time", "0.001", "--workers", "0"]
C = []
def bad(cid, *args): C.append((cid, list(args), "bad"))
def ok(cid, *args): C.append((cid, list(args), "ok"))
def q(cid, *args): C.append((cid, list(args), "?"))
sim = lambda *a: ["simulate", "-o", "{n}", *Q, *a]
# --- simulate numbers
for opt in ["--time", "--dt", "-T", "--friction", "--salt", "--pull", "--torque", "--rotation-clamp", "--turns",
            "--frame-interval", "--checkpoint-interval"]:
    for v in ["nan", "inf", "-inf", "-1", "0", "1e300"]:
        extra = []
        if opt in ("--turns",): extra = ["--rotation-clamp", "200", "--clamp-first", "--pull", "2"]
        if opt in ("--torque",): extra = ["--clamp-first", "--pull", "2"]
        if opt == "--rotation-clamp": extra = ["--clamp-first"]
        C.append((f"sim{opt}={v}", sim(SEQ, opt, v, *extra, *L) if opt not in ("--salt",) else sim(SEQ, opt, v), "?"))
for opt, vals in [("--delta-lk", ["999999999999", "-5"]), ("--threads", ["0", "-1"]), ("--seed", ["-1", "99999999999999"]),
                  ("--duplex", ["-1", "99"])]:
    for v in vals:
        q(f"sim{opt}={v}", *sim(SEQ40 if opt == "--delta-lk" else (S + "/355D.pdb" if opt == "--duplex" else SEQ), opt, v, *(["--ring"] if opt == "--delta-lk" else []), *L))
# sources
for src in ["0", "1", "2", "3", "-5", "3.5", "", " ", "acgttgcaac", "ACGTN", "1e3", "ACGT ACGT", "0x10"]:
    q(f"sim-source={src!r}", *sim(src, *L))
for f in ["ss.pdb", "rna.pdb", "protein.pdb", "multimodel.pdb", "altloc.pdb", "bulge.pdb", "crlf.pdb", "nan.pdb",
          "same_xyz.pdb", "onepair.pdb", "twopair.pdb", "empty.pdb", "header_only.pdb", "binary.pdb", "binary.cif",
          "binary.npz", "binary.fa", "binary.txt", "binary.gz", "trunc.pdb", "trunc_midline.pdb", "pdb_named.cif",
          "pdb_named.npz", "pdb_named.txt", "gz.pdb.gz", "adir", "adir.pdb", "empty.fa", "header.fa", "npz_named.pdb",
          "foreign.npz", "run/trajectory.dtraj", "run/run.json"]:
    q(f"sim-file={f}", *sim("{w}/" + f, *L))
for f in ["2D94.pdb", "1KX5.pdb", "1CGP.pdb", "329D.pdb", "fiber_models/str15/S1.pdb", "fiber_models/str01/A.pdb"]:
    q(f"sim-struct={f}", *sim(S + "/" + f, *L, "--time", "0.001"))
# traps
for t in ["0:nan", "0:-5", "0:0", "0:inf", "-1:5", "0:5:3", ":5", "0:", "a:5", "0:1e300"]:
    q(f"sim-trap={t}", *sim(SEQ, "--trap", t, *L))
q("sim-trap-dup", *sim(SEQ, "--trap", "0:5", "--trap", "0:5", *L))
q("sim-trap-on-clamped", *sim(SEQ, "--trap", "0:5", "--clamp-first", *L))
# combos
q("sim-ring-circular", *sim(SEQ40, "--ring", "--circular", *L))
q("sim-circular-deltalk", *sim(SEQ40, "--circular", "--delta-lk", "1", *L))
q("sim-circular-pull", *sim(SEQ40, "--circular", "--pull", "1", *L))
q("sim-ring-equilibrium", *sim(SEQ40, "--ring", "--equilibrium", *L))
q("sim-ring-minimize", *sim(SEQ40, "--ring", "--minimize", *L))
q("sim-rotclamp-no-turns", *sim(SEQ, "--rotation-clamp", "200", *L))
q("sim-turns-ring", *sim(SEQ40, "--ring", "--turns", "1", *L))
q("sim-torque-and-clamp", *sim(SEQ, "--torque", "5", "--rotation-clamp", "200", "--clamp-first", "--pull", "1", *L))
q("sim-minimize-free-pull", *sim(SEQ, "--pull", "2", "--minimize", *L))
q("sim-minimize-torque", *sim(SEQ, "--torque", "5", "--pull", "1", "--clamp-first", "--minimize", *L))
q("sim-equilibrium-pull", *sim(SEQ, "--pull", "2", "--equilibrium", *L))
q("sim-pull-negative-clampfirst", *sim(SEQ, "--pull", "-2", "--clamp-first", *L))
q("sim-structure-intrinsic-on-seq", *sim(SEQ, "--intrinsic", "structure", *L))
q("sim-frame-gt-time", *sim(SEQ, "--frame-interval", "100", *L))
q("sim-threads-lax", *sim(SEQ, "--threads", "2", *L))
q("sim-platform-lax", *sim(SEQ, "--platform", "CPU", *L))
q("sim-elastic-lax", *sim(SEQ, "--elastic", "plugin", *L))
q("sim-salt-lax", *sim(SEQ, "--salt", "0.5", *L))
q("sim-velocities-xtc", *sim(SEQ, "--no-export", "--xtc", *L))
# forcefields
for ff in ["nope", "{w}/adir", "{w}/empty.toml", "{w}/ff_partial.toml", "{w}/binary.toml", "{w}/pdb_named.toml", "dna-defualt", ""]:
    q(f"sim-ff={ff}", *sim(SEQ, "-f", ff, *L))
    q(f"forcefields={ff}", "forcefields", ff)
# outputs
for o in ["/proc/xx", "/dev/null", "/sys/xx", "{w}/adir.pdb", "{w}/run/run.json", "{w}/run/trajectory.dtraj/x"]:
    C.append((f"sim-out={o}", ["simulate", SEQ, "-o", o, *Q, *L], "?"))
# resume variants (on copies)
for extra in [["--frame-interval", "0.4"], ["--checkpoint-interval", "1"], ["-f", "dna-uniform"], ["--no-export"],
              ["--export"], ["--salt", "0.5"], ["--velocities"], ["--minimize"], ["--equilibrium"], ["--ring"],
              ["--trap", "0:5"], ["--platform", "CPU"], ["--intrinsic", "structure"]]:
    C.append((f"resume{extra}", ["lax-run", SEQ, "-o", "{copy:run}", "--resume", "--time", "0.004", "--no-progress", "--seed", "3", "--frame-interval", "0.2", *extra], "?"))
# analyze
A = lambda *a: ["analyze", *a, "-o", "{n}", "--no-plots"]
DT = "{w}/run/trajectory.dtraj"
for opt, v in [("--start", "1000000"), ("--start", "-1"), ("--start", "5 --stop 3"), ("--blocks", "1000000"), ("--temperature", "nan"),
               ("--temperature", "inf"), ("--exclude-ends", "-1"), ("--duplex", "-3"), ("--step", "-1"), ("--stop", "0")]:
    q(f"analyze{opt}={v}", *A(DT, opt, *v.split()))
for t in ["{w}/nope.npz", "{w}/adir", "{w}/binary.npz", "{w}/foreign.npz", "{w}/run15/final_model.npz", "{w}/ss.pdb", "{w}/empty.pdb"]:
    q(f"analyze-top={t}", *A(DT, "-t", t))
for i in ["{w}/adir", "{w}/empty.dtraj", "{w}/trunc.dtraj", "{w}/binary.dtraj", "{w}/binary.xtc", "{w}/ss.pdb", "{w}/protein.pdb",
          "{w}/multimodel.pdb", "{w}/rna.pdb", "{w}/model.npz", "{w}/afile", "{w}/run/run.json", S + "/355D.pdb", "{w}/onepair.pdb", "{w}/twopair.pdb"]:
    q(f"analyze-in={i}", *A(i))
q("analyze-circular-open", *A(DT, "--circular"))
q("analyze-ff-bad", *A(DT, "-f", "nope"))
q("analyze-ff-uniform", *A(DT, "-f", "dna-uniform"))
q("analyze-dtraj-xtc-topology-dcd", *A("{w}/binary.xtc", "-t", S + "/355D.pdb"))
# structure commands
for cmd in ["steps", "pairs", "build"]:
    out = ["-o", "{n}.npz"] if cmd == "build" else []
    for f in ["ss.pdb", "rna.pdb", "protein.pdb", "multimodel.pdb", "altloc.pdb", "bulge.pdb", "crlf.pdb", "nan.pdb", "same_xyz.pdb",
              "onepair.pdb", "twopair.pdb", "empty.pdb", "header_only.pdb", "binary.pdb", "binary.cif", "trunc.pdb", "trunc_midline.pdb",
              "pdb_named.cif", "pdb_named.npz", "gz.pdb.gz", "adir", "npz_named.pdb", "model.npz"]:
        q(f"{cmd}-file={f}", cmd, "{w}/" + f, *out)
    for opt, v in [("--model", "0"), ("--model", "-1"), ("--model", "99"), ("--model", "2"), ("--map", "X"), ("--map", "DA=Z"),
                   ("--map", "=A"), ("--ignore", ""), ("--pairs", "{w}/nope.txt"), ("--pairs", "{w}/pairs_empty.txt"),
                   ("--pairs", "{w}/pairs_bad.txt"), ("--pairs", "{w}/pairs_dup.txt"), ("--pairs", "{w}/pairs_self.txt"),
                   ("--pairs", "{w}/adir"), ("--duplex", "99"), ("--duplex", "-1"), ("--altloc", "")]:
        src = "{w}/multimodel.pdb" if opt == "--model" else S + "/355D.pdb"
        q(f"{cmd}{opt}={v}", cmd, src, opt, v, *out)
    for f in ["2D94.pdb", "1KX5.pdb", "1CGP.pdb", "fiber_models/str15/S1.pdb"]:
        q(f"{cmd}-struct={f}", cmd, S + "/" + f, *out)
for c in ["{w}/adir", "{w}/afile", "/proc/x.csv", "{w}/run/run.json"]:
    q(f"steps-csv={c}", "steps", S + "/355D.pdb", "--csv", c)
    q(f"pairs-csv={c}", "pairs", S + "/355D.pdb", "--csv", c)
for a in [["--sequence", ""], ["--sequence", "acgt"], ["--sequence", "A"], ["--sequence", "ACGN"], ["--sequence", "AC", S + "/355D.pdb"], []]:
    q(f"build{a}", "build", *a, "-o", "{n}.npz")
for o in ["{w}/adir", "{w}/.npz", "/proc/x.npz", "{w}/adir.pdb"]:
    q(f"build-o={o}", "build", "--sequence", "ACGT", "-o", o)
for m in ["{w}/binary.npz", "{w}/foreign.npz", "{w}/pdb_named.npz", "{w}/adir", "{w}/run/checkpoint.npz"]:
    q(f"rebuild-in={m}", "rebuild", m, "-o", "{n}.pdb", "--no-minimize")
for o in ["{w}/adir", "{w}/adir.pdb", "{n}.cif", "{n}.PDB", "{n}"]:
    q(f"rebuild-o={o}", "rebuild", "{w}/model.npz", "-o", o, "--no-minimize")
# validate
q("validate-only-bad", "validate", "--only", "nope", "-o", "{n}")
q("validate-out-file", "validate", "--only", "helix", "-o", "{w}/afile")
# round 7: output folders of every writer, a report replaced, simulate --charge/--cutoff-debye, --clamp-k bound
for o in ["{w}/proj", "{w}/rep"]:
    q(f"sim-out-folder={o}", "simulate", SEQ, "-o", o, *Q, *L)
    q(f"protocol-out-folder={o}", "protocol", "hat", "--turns", "0", *P, "-o", o)
    q(f"ensemble-out-folder={o}", "ensemble", str(Path(__file__).resolve().parents[2] / "examples" / "force_extension.toml"), "-o", o, "--workers", "0")
    q(f"analyze-out-folder={o}", "analyze", "{w}/run/trajectory.dtraj", "-o", o, "--no-plots")
q("validate-out-project", "validate", "--only", "helix", "-o", "{w}/proj")
q("validate-over-report", "validate", "--only", "helix", "-o", "{w}/rep")
for v in ["nope", "", "MANNING", "0.48"]:
    q(f"sim-charge={v!r}", *sim(SEQ, "--charge", v))
for v in ["nan", "-1", "0", "1", "1e300"]:
    q(f"sim-cutoff-debye={v}", *sim(SEQ, "--cutoff-debye", v))
q("lax-charge", *sim(SEQ, "--charge", "manning", *L))
for v in ["1e5", "1e7"]:
    q(f"hat-clamp-k-stiff={v}", "protocol", "hat", *P, "-o", "{n}", "--turns", "0", "--clamp-k", v)
for v in ["373", "400", "1e9"]:
    q(f"sim-T-hot={v}", *sim(SEQ, "-T", v, *L))
# ensemble
for f in sorted(p for p in (W / "spec").iterdir() if p.name not in ("linspace_huge.toml", "cross_huge.toml", "replicas_huge.toml")):
    q(f"ensemble-{f.name}", "ensemble", str(f), "-o", "{n}", "--workers", "0", "--no-progress")
for s in ["{w}/nope.toml", "{w}/adir", "{w}/binary.toml", S + "/355D.pdb"]:
    q(f"ensemble-specfile={s}", "ensemble", s, "-o", "{n}", "--workers", "0")
q("ensemble-out-file", "ensemble", str(Path(__file__).resolve().parents[2] / "examples" / "force_extension.toml"), "-o", "{w}/afile", "--workers", "0")
q("ensemble-out-run", "ensemble", str(Path(__file__).resolve().parents[2] / "examples" / "force_extension.toml"), "-o", "{copy:run}", "--workers", "0")
# protocols
PR = lambda kind, *a: ["protocol", kind, *P, "-o", "{n}", *a]
q("hat-turns-dup", *PR("hat", "--turns", "0,0"))
q("hat-force-dup", *PR("hat", "--turns", "0", "--force", "1,1"))
q("hat-force-neg", *PR("hat", "--turns", "0", "--force", "-1"))
q("fx-force-zero", *PR("force-extension", "--force", "0"))
q("fx-force-neg", *PR("force-extension", "--force", "-1"))
q("fx-force-dup", *PR("force-extension", "--force", "1,1"))
q("rings-dlk-dup", *PR("rings", "--delta-lk", "1,1"))
for v in ["0", "-1", "nan", "inf", "1e300"]:
    q(f"hat-clamp-k={v}", *PR("hat", "--turns", "0", "--clamp-k", v))
for v in ["0", "-1", "nan", "inf"]:
    q(f"hat-equil={v}", *PR("hat", "--turns", "0", "--equilibration", v))
    q(f"hat-time={v}", *PR("hat", "--turns", "0", "--time", v))
    q(f"hat-salt={v}", *PR("hat", "--turns", "0", "--salt", v))
    q(f"hat-temp={v}", *PR("hat", "--turns", "0", "--temperature", v))
for s in ["0", "1", "2", "3", "abc", "", "{w}/nope.pdb", S + "/355D.pdb", "{w}/model.npz", "{w}/ss.pdb", "{w}/adir", "ACGTN", "-5"]:
    q(f"hat-source={s!r}", "protocol", "hat", "--turns", "0", "--time", "0.001", "--workers", "0", "--source", s, "-o", "{n}")
    q(f"rings-source={s!r}", "protocol", "rings", "--delta-lk", "0", "--time", "0.001", "--workers", "0", "--source", s, "-o", "{n}")
for ff in ["nope", "{w}/binary.toml", ""]:
    q(f"hat-ff={ff}", *PR("hat", "--turns", "0", "--forcefield", ff))
q("hat-settle-static", *PR("hat", "--turns", "0", "--settle", "1"))
q("hat-sweep-one", *PR("hat", "--turns", "0", "--start", "sweep"))
q("hat-out-file", "protocol", "hat", "--turns", "0", "--time", "0.001", "--workers", "0", "--source", "40", "-o", "{w}/afile")
q("hat-force-60", *PR("hat", "--turns", "0", "--force", "60"))
q("hat-turns-semicolon", *PR("hat", "--turns", "0;1"))
q("rings-dlk-float-str", *PR("rings", "--delta-lk", "1.0"))
q("rings-dlk-huge", *PR("rings", "--delta-lk", "1e30"))
q("fx-turns-given", *PR("force-extension", "--force", "1", "--turns", "0,1"))
q("protocol-bare", "protocol")
q("protocol-unknown", "protocol", "nope")

import shutil
snap = lambda: {str(p): (p.stat().st_size, p.stat().st_mtime_ns) for p in W.rglob("*") if p.is_file() and "out" not in p.relative_to(W).parts[:1] and "copies" not in p.relative_to(W).parts[:1]}
out = W / "out"; out.mkdir(exist_ok=True); (W / "copies").mkdir(exist_ok=True)
res = []
for i, (cid, args, exp) in enumerate(C):
    if only and only not in cid: continue
    n = str(out / f"c{i}")
    a2 = []
    for a in args:
        if a.startswith("{copy:"):
            name = a[6:-1]; dst = W / "copies" / f"c{i}"; shutil.copytree(W / name, dst, dirs_exist_ok=True); a = str(dst)
        a2.append(a.replace("{w}", str(W)).replace("{n}", n))
    before = snap()
    t0 = time.time()
    os.chdir(W / "out")
    try:
        r = CliRunner().invoke(main, a2, catch_exceptions=True)
        rc, so, se = r.exit_code, r.stdout, r.stderr
        if r.exception is not None and not isinstance(r.exception, SystemExit):
            import traceback
            se += "\nTraceback (in-process): " + "".join(traceback.format_exception(r.exception))[-800:]
    except BaseException as e:
        rc, so, se = "EXC", "", repr(e)
    dt = time.time() - t0
    after = snap()
    changed = [k for k in before if after.get(k) != before[k]]
    errl = [l for l in se.splitlines() if l.strip() and not l.startswith("dnarod: warning")]
    flags = []
    if "Traceback" in se: flags.append("TRACEBACK")
    if rc == "TIMEOUT": flags.append("TIMEOUT")
    elif rc not in (0, 2): flags.append(f"rc={rc}")
    if rc == 2 and len(errl) != 1: flags.append(f"stderr-lines={len(errl)}")
    if rc == 2 and so.strip(): flags.append("stdout-on-error")
    if changed: flags.append("CHANGED:" + ",".join(Path(c).name for c in changed))
    if rc == 0 and exp == "bad": flags.append("ACCEPTED")
    r = dict(id=cid, args=a2, rc=rc, flags=flags, err=se.strip()[-600:], out=so.strip()[-300:], secs=round(dt, 1))
    res.append(r)
    print(f"{cid:45s} rc={rc} {dt:5.1f}s {' '.join(flags)} | {(errl[-1] if errl else so.strip().splitlines()[-1] if so.strip() else '')[:200]}", flush=True)
Path(sys.argv[4] if len(sys.argv) > 4 else W / "probe.json").write_text(json.dumps(res, indent=1))
