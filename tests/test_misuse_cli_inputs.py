"""Misuse classes found by probing every command and option with bad values and held-out inputs: each case is
one line on stderr naming the option or file, exit status 2, nothing on stdout, and every file that existed
before unchanged. One case per class; the classes are listed in docs/misuse.md."""
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from dnarod.cli.main import main

ROOT = Path(__file__).resolve().parent.parent
PDB = ROOT / "data" / "structures" / "355D.pdb"
SEQ = "ACGTTGCAAC"
LAX = ["--engine", "lax", "--time", "0.001", "--no-progress", "--seed", "3", "--frame-interval", "0.2"]
PROTO = ["--time", "0.001", "--workers", "0", "-o", "{w}/n"]


@pytest.fixture
def work(tmp_path):
    """Small bad inputs (no runs): a PDB under the wrong suffixes, a binary file, spec files."""
    text = PDB.read_text()
    (tmp_path / "pdb_named.npz").write_text(text)
    (tmp_path / "run.json").write_text('{"format": "dnarod-run"}\n')
    (tmp_path / "binary.fa").write_bytes(np.random.default_rng(1).integers(0, 256, 2000, dtype=np.uint8).tobytes())
    base = '[base]\nsource = "ACGTACGTAC"\ntime_ns = 0.001\nengine = "lax"\nexcluded_volume = false\n' \
           'electrostatics = false\n'
    specs = {
        "dt_huge": base + "dt_ps = 5\n",
        "time_huge": base.replace("time_ns = 0.001", "time_ns = 1e300"),
        "eq_ring": base.replace('"ACGTACGTAC"', '"' + "ACGT" * 10 + '"') + 'ring = true\nstart = "equilibrium"\n',
        "discard_all": base + "[analysis]\ndiscard_ns = 5\n",
        "blocks_one": base + "[analysis]\nblocks = 1\n",
        "linspace_huge": base + "[axes]\nforce_pN = {linspace = [0, 1, 1000000000]}\n",
        "replicas_huge": "[ensemble]\nreplicas = 1000000000\n" + base,
        "cross_huge": base + "[axes]\nforce_pN = {linspace = [0, 1, 2000]}\ntemperature_K = {linspace = [290, 310, "
                             "2000]}\n",
        "fasta_binary": '[base]\ntime_ns = 0.001\n[axes]\nfasta = "binary.fa"\n',
        "not_a_protocol": '[ensemble]\nprotocol = "os:getcwd"\n' + base,
        "stiff_clamp": base + "clamp_first = true\nforce_pN = 1\nrotation_clamp_kJ_mol = 1e300\n",
        "hat_time_huge": '[ensemble]\nprotocol = "magnetic-tweezers"\n[base]\nsource = "40"\ntime_ns = 1e300\n'
                         'force_pN = 1\nrotation_clamp_kJ_mol = 250\n[axes]\nturns = [0, 0.5]\n',
        "rings_sigma": '[ensemble]\nprotocol = "rings"\n[base]\nsource = "60"\ntime_ns = 0.01\nring = true\n[axes]\n'
                       'delta_lk = [0, 3]\n',
    }
    for name, t in specs.items():
        (tmp_path / f"{name}.toml").write_text(t)
    (tmp_path / "rna.pdb").write_text(_rna_text(text))
    from dnarod.structure.inputs import load_model
    from dnarod.core.trajectory import HEADER_SIZE, Trajectory

    m = load_model("ACGTACGTAC")
    Trajectory([0.0, 1.0], np.repeat(m.positions[None], 2, 0), np.repeat(m.frames[None], 2, 0),
               [0, 10]).save(tmp_path / "t.dtraj")
    data = (tmp_path / "t.dtraj").read_bytes()
    (tmp_path / "t.dtraj").write_bytes(data[:HEADER_SIZE + 100])   # killed before its first frame was complete
    m.save(tmp_path / "final_model.npz")
    return tmp_path


def _rna_text(pdb_text):
    """355D made into an RNA duplex: T -> U (methyl dropped), an O2' on every sugar."""
    out = []
    for line in pdb_text.splitlines():
        if not line.startswith(("ATOM", "HETATM")) or line[17:20].strip() not in ("A", "C", "G", "T"):
            continue
        name, res = line[12:16].strip(), line[17:20].strip()
        if res == "T" and name in ("C7", "C5M"):
            continue
        line = line[:17] + f"{'U' if res == 'T' else res:>3s}" + line[20:]
        out.append(line)
        if name in ("C2'", "C2*"):
            x, y, z = (float(line[i:i + 8]) for i in (30, 38, 46))
            out.append(line[:12] + " O2'" + line[16:30] + f"{x + 1.0:8.3f}{y + 0.9:8.3f}{z + 0.3:8.3f}" + line[54:])
    return "\n".join(out) + "\nEND\n"


def _snapshot(folder):
    return {p: p.read_bytes() for p in sorted(Path(folder).rglob("*")) if p.is_file()}


def _hold_lock(w):
    """A second process writing into W/busy: the lock is held (as a running `dnarod simulate` holds it)."""
    from dnarod.core.io import folder_lock

    cm = folder_lock(w / "busy")
    cm.__enter__()
    return cm


# (id, arguments, words the message must contain, set-up returning a context to close or None)
CASES = [
    # two processes writing one folder
    ("run-into-folder-in-use", ["lax-run", SEQ, "-o", "{w}/busy", *LAX[2:]], ["busy", "in use by another dnarod "
                                                                             "process", "pid"], _hold_lock),
    ("overwrite-folder-in-use", ["lax-run", SEQ, "-o", "{w}/busy", "--overwrite", *LAX[2:]], ["in use"], _hold_lock),
    # duplicate list entries
    ("trap-twice-on-one-node", ["simulate", SEQ, "-o", "{w}/n", *LAX, "--trap", "1:5", "--trap", "-10:3"],
     ["--trap '-10:3'", "base pair 1 already has a trap"], None),
    ("protocol-turns-repeated", ["protocol", "hat", "--source", "40", "--turns", "0,0", *PROTO],
     ["--turns", "repeated values"], None),
    ("protocol-forces-repeated", ["protocol", "force-extension", "--source", "40", "--force", "1,1.0", *PROTO],
     ["--force", "repeated values"], None),
    # options the chosen engine or settings would silently ignore
    ("lax-with-threads", ["simulate", SEQ, "-o", "{w}/n", *LAX, "--threads", "2"], ["--threads 2", "lax engine"],
     None),
    ("lax-with-elastic", ["simulate", SEQ, "-o", "{w}/n", *LAX, "--elastic", "plugin"], ["--elastic plugin"], None),
    ("lax-with-salt", ["simulate", SEQ, "-o", "{w}/n", *LAX, "--salt", "0.5"], ["--salt 0.5", "off here"], None),
    ("xtc-without-export", ["simulate", SEQ, "-o", "{w}/n", *LAX, "--no-export", "--xtc"], ["--xtc", "--no-export"],
     None),
    # files whose content is not what the command reads (numpy's "allow_pickle" advice no longer shown)
    ("model-is-a-pdb-text", ["rebuild", "{w}/pdb_named.npz", "-o", "{w}/x.pdb", "--no-minimize"],
     ["pdb_named.npz", "cannot read dnarod model file (it is a PDB text file"], None),
    ("model-is-json", ["simulate", "{w}/run.json", "-o", "{w}/n", *LAX], ["run.json", "it is a JSON text file"], None),
    # empty or conflicting names in the structure options (they matched nothing, silently)
    ("map-empty-name", ["pairs", str(PDB), "--map", "=A"], ["--map '=A'", "NAME is empty"], None),
    ("map-twice-differently", ["steps", str(PDB), "--map", "XX=A", "--map", "xx=C"], ["already mapped to A"], None),
    ("ignore-empty", ["build", str(PDB), "-o", "{w}/m.npz", "--ignore", ""], ["--ignore ''"], None),
    ("altloc-empty", ["pairs", str(PDB), "--altloc", ""], ["--altloc ''"], None),
    ("ignore-and-map", ["pairs", str(PDB), "--ignore", "SPM", "--map", "SPM=A"], ["--ignore SPM", "--map"], None),
    # analyze: a refusal found while analysing used to follow a line already printed on stdout
    ("analyze-single-structure", ["analyze", str(PDB), "-o", "{w}/n", "--no-plots"],
     ["355D.pdb", "a single frame (one structure)", "dnarod steps"], None),
    ("analyze-truncated-trajectory", ["analyze", "{w}/t.dtraj", "-o", "{w}/n", "--no-plots"],
     ["t.dtraj", "no complete frame", "truncated"], None),
    ("analyze-rna", ["analyze", "{w}/rna.pdb", "-o", "{w}/n", "--no-plots"], ["rna.pdb", "other than A, C, G, T"],
     None),
    # protocol sources the protocols cannot build
    ("protocol-source-file", ["protocol", "hat", "--turns", "0", "--source", str(PDB), *PROTO],
     ["--source", "not from a file"], None),
    ("protocol-source-too-short", ["protocol", "torque-turns", "--turns", "0", "--source", "3", *PROTO],
     ["--source 3", "at least 8"], None),
    ("protocol-source-letters", ["protocol", "rings", "--delta-lk", "0", "--source", "ACGU" * 10, *PROTO],
     ["--source", "not a node count or a DNA sequence"], None),
    # protocol member times that would never finish (a traceback, a MemoryError, or a hang)
    ("protocol-time-huge", ["protocol", "hat", "--turns", "0", "--source", "40", "--time", "1e300", *PROTO[2:]],
     ["--time (time_ns)", "more than 10000 ns"], None),
    ("protocol-equilibration-huge", ["protocol", "rings", "--delta-lk", "0", "--source", "40", *PROTO,
                                     "--equilibration", "1e12"], ["--equilibration", "more than 10000 ns"], None),
    # the turn-sweep starts left the product (research/turn_sweeps): refused as an unknown choice
    ("protocol-start-sweep-unknown", ["protocol", "hat", "--turns", "0", "--source", "40", "--start", "sweep", *PROTO],
     ["--start", "'sweep' is not one of 'static', 'exchange'"], None),
    # a load so stiff it sets the time step (it used to be blamed on --time/--dt)
    ("rotation-clamp-huge", ["simulate", SEQ, "-o", "{w}/n", *LAX, "--clamp-first", "--rotation-clamp", "1e300"],
     ["--rotation-clamp 1e+300", "use at most"], None),
    ("trap-huge", ["simulate", SEQ, "-o", "{w}/n", *LAX, "--trap", "3:1e300"], ["--trap 3:1e+300", "use at most"],
     None),
    # ensemble members refused on the client before any member runs (they used to fail one by one, exit 1)
    ("ensemble-dt-above-limit", ["ensemble", "{w}/dt_huge.toml", "-o", "{w}/n", "--workers", "0"],
     ["member 0", "--dt 5", "stability limit"], None),
    ("ensemble-too-many-steps", ["ensemble", "{w}/time_huge.toml", "-o", "{w}/n", "--workers", "0"],
     ["member 0", "steps, more than"], None),
    ("ensemble-equilibrium-ring", ["ensemble", "{w}/eq_ring.toml", "-o", "{w}/n", "--workers", "0"],
     ["member 0", "equilibrium", "circular"], None),
    ("ensemble-discard-all", ["ensemble", "{w}/discard_all.toml", "-o", "{w}/n", "--workers", "0"],
     ["discard_ns = 5", "time_ns"], None),
    ("ensemble-stiff-clamp", ["ensemble", "{w}/stiff_clamp.toml", "-o", "{w}/n", "--workers", "0"],
     ["member 0", "--rotation-clamp", "use at most"], None),
    ("ensemble-one-block", ["ensemble", "{w}/blocks_one.toml", "-o", "{w}/n", "--workers", "0"],
     ["[analysis] blocks", ">= 2"], None),
    ("ensemble-protocol-member-time", ["ensemble", "{w}/hat_time_huge.toml", "-o", "{w}/n", "--workers", "0"],
     ["member 0", "time_ns", "more than 10000 ns"], None),
    ("ensemble-protocol-ring-sigma", ["ensemble", "{w}/rings_sigma.toml", "-o", "{w}/n", "--workers", "0"],
     ["member 1", "sigma"], None),
    # sizes that fill the memory before anything runs
    ("ensemble-linspace-huge", ["ensemble", "{w}/linspace_huge.toml", "-o", "{w}/n", "--workers", "0"],
     ["linspace of 1000000000 values", "100000"], None),
    ("ensemble-replicas-huge", ["ensemble", "{w}/replicas_huge.toml", "-o", "{w}/n", "--workers", "0"],
     ["1000000000 members", "more than 100000"], None),
    ("ensemble-cross-huge", ["ensemble", "{w}/cross_huge.toml", "-o", "{w}/n", "--workers", "0"],
     ["2000 x 2000", "more than 100000"], None),
    ("protocol-workers-huge", ["protocol", "hat", "--turns", "0", "--source", "40", *PROTO[:2], "--workers",
                               "100000", "-o", "{w}/n"], ["--workers 100000", "per core"], None),
    ("ensemble-workers-huge", ["ensemble", "{w}/dt_huge.toml", "-o", "{w}/n", "--workers", "100000"],
     ["--workers 100000", "per core"], None),
    # unreadable or wrong inputs that raised a Python error or were silently ignored
    ("ensemble-binary-fasta", ["ensemble", "{w}/fasta_binary.toml", "-o", "{w}/n", "--workers", "0"],
     ["binary.fa", "not a FASTA text file"], None),
    ("ensemble-protocol-without-hooks", ["ensemble", "{w}/not_a_protocol.toml", "-o", "{w}/n", "--workers", "0"],
     ["os:getcwd", "not a registered name", "known protocols"], None),
]


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_misuse_class_is_one_line_exit_2_and_changes_nothing(work, case, assert_refused):
    _, args, words, setup = case
    assert_refused.case(work, args, words, setup)


def test_resume_refused_while_the_run_goes_on(tmp_path):
    """A resume (or a second run) while another process writes the folder is refused; once it is free the
    same resume runs."""
    from dnarod.core.io import folder_lock

    out = tmp_path / "r"
    r = CliRunner().invoke(main, ["lax-run", SEQ, "-o", str(out), *LAX[2:]])
    assert r.exit_code == 0, r.output
    with folder_lock(out):  # (the lock file exists only while the lock is held)
        before = _snapshot(out)
        r = CliRunner().invoke(main, ["lax-run", SEQ, "-o", str(out), "--resume", "--time", "0.002", *LAX[4:]])
        assert r.exit_code == 2 and "in use by another dnarod process" in r.stderr, r.output
        assert _snapshot(out) == before
    r = CliRunner().invoke(main, ["lax-run", SEQ, "-o", str(out), "--resume", "--time", "0.002", *LAX[4:]])
    assert r.exit_code == 0, r.output
    assert r.stdout.startswith("resumed from step ")


def test_structure_format_is_read_from_the_content(tmp_path):
    """A PDB file named .cif and an mmCIF file named .pdb are read as what they are (same pairs)."""
    import gemmi

    (tmp_path / "pdb_named.cif").write_text(PDB.read_text())
    st = gemmi.read_structure(str(PDB))
    st.setup_entities()
    st.make_mmcif_document().write_file(str(tmp_path / "cif_named.pdb"))
    outs = []
    for f in (PDB, tmp_path / "pdb_named.cif", tmp_path / "cif_named.pdb"):
        r = CliRunner().invoke(main, ["pairs", str(f)])
        assert r.exit_code == 0, r.output
        outs.append([ln.split()[:3] for ln in r.stdout.splitlines() if ln.strip()[:1].isdigit()])
    assert len(outs[0]) == 12 and outs[1] == outs[0] and outs[2] == outs[0]


def test_unwritable_output_names_the_file_not_a_temporary(tmp_path):
    if not Path("/proc").is_dir():
        pytest.skip("no /proc here")
    r = CliRunner().invoke(main, ["steps", str(PDB), "--csv", "/proc/x.csv"])
    assert r.exit_code == 2
    err = r.stderr.strip()
    assert "\n" not in err and "cannot write /proc/x.csv" in err and ".tmp" not in err, err


def test_interrupt_keeps_files_and_says_how_to_continue(tmp_path, monkeypatch):
    """Ctrl-C: one line saying what is kept and how to go on, exit status 130 (not click's "Aborted!", 1)."""
    import dnarod.run.api as api

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(api, "_execute", interrupted)
    r = CliRunner().invoke(main, ["lax-run", SEQ, "-o", str(tmp_path / "r"), *LAX[2:]])
    assert r.exit_code == 130, r.output
    assert "interrupted" in r.stderr and "--resume" in r.stderr and "\n" not in r.stderr.strip()


def test_api_repeated_axis_values_and_non_protocols(tmp_path):
    """The Python API refuses what the command line refuses."""
    from dnarod.workflows.ensemble import Ensemble
    from dnarod.core.errors import DnarodError
    from dnarod.workflows.protocols import hat_curve

    with pytest.raises(DnarodError, match="repeated values"):
        hat_curve([0, 1, 0], tmp_path / "h", source="40", base=dict(time_ns=0.001), workers=0)
    with pytest.raises(DnarodError, match="none of build, reduce, execute"):
        Ensemble.from_dict({"base": {"source": "ACGTACGTAC"}}, tmp_path / "e", protocol=object())
    assert not any(tmp_path.iterdir())


def test_legitimate_stiff_loads_and_default_clamp_still_run(tmp_path):
    """The stiffness bound leaves ordinary traps and the protocols' clamp (250 kJ/mol) alone."""
    from dnarod.run.api import check_load_stiffness
    from dnarod.run import RunSpec
    from dnarod.structure.inputs import load_model
    from dnarod.physics.loads import tweezers

    model = load_model("40")
    for clamp, traps in ((250.0, ((3, 1000.0),)), (1e5, ())):
        loads = tweezers(model, 1.0, None, clamp, 0.0, anchor="surface", traps=traps)
        check_load_stiffness(RunSpec(source="40", loads=loads), model)   # no error
    loads = tweezers(model, 1.0, None, 1e7, 0.0, anchor="surface")
    with pytest.raises(Exception, match=r"--rotation-clamp 1e\+07 .*use at most"):
        check_load_stiffness(RunSpec(source="40", loads=loads), model)


def test_protocol_folder_of_other_settings_is_refused(tmp_path):
    """A protocol run again into its folder with other settings (or another protocol) is refused, its files
    unchanged; the same settings reuse the finished member; --overwrite runs it again."""
    out = tmp_path / "hat"
    args = ["protocol", "hat", "--turns", "0", "--source", "40", "--equilibration", "0.001", "--workers", "0",
            "-o", str(out)]
    r = CliRunner().invoke(main, [*args, "--time", "0.001"])
    assert r.exit_code == 0, r.output
    before = _snapshot(out)
    for other, words in ((["--time", "0.002"], ["time_ns 0.001 -> 0.002", "--overwrite"]),
                         (["--time", "0.001", "--salt", "0.3"], ["salt_M 0.15 -> 0.3"])):
        r = CliRunner().invoke(main, [*args, *other])
        assert r.exit_code == 2 and r.stdout == "", r.output
        assert all(w in r.stderr for w in words) and "\n" not in r.stderr.strip(), r.stderr
        assert _snapshot(out) == before
    tt = ["protocol", "torque-turns", *args[2:], "--time", "0.001"]
    r = CliRunner().invoke(main, tt)
    assert r.exit_code == 2 and "a magnetic_tweezers run, not torque_turns" in r.stderr, r.output
    r = CliRunner().invoke(main, [*args, "--time", "0.001"])      # same settings: the member is reused
    assert r.exit_code == 0, r.output
    assert (out / "members").exists() and _snapshot(out / "members") == {
        p: d for p, d in before.items() if "members" in p.parts}
    from dnarod.workflows.protocols.folder import check_protocol_folder

    check_protocol_folder(out, "torque_turns", {}, overwrite=True)     # --overwrite lets the run go on

