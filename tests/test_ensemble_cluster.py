"""Ensembles on real clusters: wrong, unreachable or non-dask schedulers, Ctrl-C, a lost scheduler and a
full disk (one line, no dask traceback), private local clusters, a TLS-secured scheduler, and protocols named only
from the registry. Each fault is a row of docs/faults_cluster.md."""
import http.server
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from dnarod.cli.main import main
from dnarod.workflows.ensemble.cluster import SchedulerError, client_for, connect
from dnarod.workflows.ensemble.protocol import known_protocols, resolve_protocol
from dnarod.workflows.ensemble.schema import SpecError

ROOT = Path(__file__).parents[1]
NULL_SPEC = '[ensemble]\nprotocol = "null"\n[base]\nsource = "ACGTACGTAC"\ntime_ns = 0.001\n[axes]\nforce_pN = [1, 2]\n'

# An installed package that declares a protocol as an entry point (group dnarod.protocols): members that sleep,
# so a test can interrupt them; "started" marks a member that has begun.
TESTPROTO = '''
import sys
import time
from pathlib import Path


class Sleepy:
    keys = {"sleep_s": float}

    def execute(self, settings, member_dir, analysis=None):
        Path(member_dir, "started").write_text("")
        print("a sleepy member started", file=sys.stderr, flush=True)
        time.sleep(settings["sleep_s"])
        return {"slept_s": settings["sleep_s"]}


SLEEPY = Sleepy()
'''

# A disk that fills as members finish: every result.json write fails with ENOSPC, in the command and in its
# worker processes (they start with the same PYTHONPATH). Patched where dnarod's atomic writes make their file.
FULL_DISK = '''
import errno
import os

if os.environ.get("DNAROD_TEST_FULL_DISK"):
    # every whole-file write of dnarod creates its hidden temporary file with os.open (dnarod.core.io.atomic_path):
    # the members' result.json cannot be written
    _open = os.open

    def full_open(path, flags, *a, **k):
        if os.path.basename(os.fspath(path)).startswith(".result.json") and flags & os.O_CREAT:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return _open(path, flags, *a, **k)

    os.open = full_open
'''


@pytest.fixture(scope="module")
def pkgs(tmp_path_factory):
    """A folder for PYTHONPATH: the entry-point package ``dnarod-testproto`` and the full-disk ``sitecustomize``."""
    d = tmp_path_factory.mktemp("pkgs")
    (d / "dnarod_testproto.py").write_text(TESTPROTO)
    info = d / "dnarod_testproto-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: dnarod-testproto\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[dnarod.protocols]\nsleepy = dnarod_testproto:SLEEPY\n")
    (d / "sitecustomize.py").write_text(FULL_DISK)
    return d


def _env(pkgs, **extra):
    return dict(os.environ, PYTHONPATH=os.pathsep.join([str(pkgs), str(ROOT)]), **extra)


def _as_from_a_terminal():
    # a command started from a terminal has the default Ctrl-C; one started by a background job (a CI runner's
    # `cmd &`) inherits SIGINT ignored, and would rightly ignore the Ctrl-C these tests send
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _dnarod(args, env, **kw):
    return subprocess.Popen([sys.executable, "-c", "from dnarod.cli.main import main; main()", *args], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                            preexec_fn=_as_from_a_terminal, **kw)


def _wait_for(pattern_dir, pattern, p, limit=60.0):
    deadline = time.time() + limit
    while time.time() < deadline and p.poll() is None:
        if list(Path(pattern_dir).glob(pattern)):
            return True
        time.sleep(0.05)
    return False


def _no_noise(stderr):
    """No traceback and no dask log record reached the terminal."""
    assert "Traceback" not in stderr, stderr
    assert "distributed." not in stderr and "Compute Failed" not in stderr, stderr


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _listening(pids):
    """``(pid, ip, port)`` of the TCP sockets listening in these processes (psutil: ``ss -ltnp``)."""
    psutil = pytest.importorskip("psutil")
    out = []
    for pid in pids:
        try:
            conns = psutil.Process(pid).net_connections(kind="inet")
        except psutil.NoSuchProcess:
            continue
        out += [(pid, c.laddr.ip, c.laddr.port) for c in conns if c.status == psutil.CONN_LISTEN]
    return out


def _speaks_http(port):
    """Whether what listens at 127.0.0.1:port answers an HTTP request."""
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=2) as s:
            s.sendall(b"GET / HTTP/1.0\r\n\r\n")
            s.settimeout(1.0)
            return s.recv(5) == b"HTTP/"
    except OSError:
        return False


# ------------------------------------------------------------------------------------------------------------
# what listens at --scheduler, if not dask

class _Server(threading.Thread):
    """A TCP server on 127.0.0.1 that greets each connection with ``greeting`` (None: says nothing; b"": closes)."""

    def __init__(self, greeting):
        super().__init__(daemon=True)
        self.greeting = greeting
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen()
        self.port = self.sock.getsockname()[1]
        self.conns = []

    def run(self):
        while True:
            try:
                c, _ = self.sock.accept()
            except OSError:
                return
            if self.greeting == b"":
                c.close()
                continue
            if self.greeting is not None:
                c.sendall(self.greeting)
            self.conns.append(c)

    def close(self):
        self.sock.close()
        for c in self.conns:
            c.close()


def _http_server():
    srv = http.server.HTTPServer(("127.0.0.1", 0), http.server.SimpleHTTPRequestHandler)
    srv.RequestHandlerClass.log_message = lambda *a: None
    threading.Thread(target=srv.serve_forever, daemon=True).start()
    return srv, srv.server_address[1]


@pytest.mark.parametrize("kind, words", [
    ("http", ["found an HTTP server, not a dask scheduler", "8786"]),
    ("silent", ["accepted the connection but sent nothing", "not a dask scheduler"]),
    ("ssh", ["found an SSH server that is not a dask scheduler", "SSH-2.0-OpenSSH_9.6"]),
    ("binary", ["found a server that is not a dask scheduler", "not dask's handshake"]),   # was a MemoryError
    ("closes", ["closed the connection at once"]),
    ("refused", ["nothing listens on port", "connection refused"]),
])
def test_non_dask_scheduler_address_is_one_line_within_timeout(tmp_path, kind, words):
    srv = None
    if kind == "http":
        srv, port = _http_server()
    elif kind == "refused":
        port = _free_port()
    else:
        srv = _Server({"silent": None, "ssh": b"SSH-2.0-OpenSSH_9.6\r\n", "binary": b"\xff" * 64,
                       "closes": b""}[kind])
        srv.start()
        port = srv.port
    spec = tmp_path / "s.toml"
    spec.write_text(NULL_SPEC)
    address = f"tcp://127.0.0.1:{port}"
    try:
        t0 = time.perf_counter()
        with pytest.raises(SchedulerError, match=words[0]):
            connect(address, timeout=2)
        took = time.perf_counter() - t0
        r = CliRunner().invoke(main, ["ensemble", str(spec), "-o", str(tmp_path / "o"), "--scheduler", address,
                                      "--timeout", "1", "--no-progress"])
    finally:
        if kind == "http":
            srv.shutdown()
        elif srv is not None:
            srv.close()
    assert r.exit_code == 2, r.output
    lines = r.output.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"dnarod: error: --scheduler tcp://127.0.0.1:{port}: "), r.output
    assert all(w in lines[0] for w in words), lines[0]
    assert took < 2 + 5, took                      # not a hang: the probe is bounded by the timeout (2 s)
    assert not (tmp_path / "o").exists()           # nothing written


def test_dask_dashboard_port_is_named(tmp_path):
    """The dashboard's HTTP server given as --scheduler (8787 typed for 8786): named as the dashboard."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=0, processes=False, host="127.0.0.1", protocol="tcp://",
                      dashboard_address="127.0.0.1:0") as cluster:
        http_port = cluster.scheduler.http_server.port
        with pytest.raises(SchedulerError, match=rf"--scheduler tcp://127.0.0.1:{http_port}: found the dask "
                                                 r"dashboard \(an HTTP server\), not the scheduler; the scheduler "
                                                 r"usually listens on port 8786"):
            connect(f"tcp://127.0.0.1:{http_port}", timeout=2)
        c = connect(cluster.scheduler_address, timeout=5)       # the scheduler itself: connects
        assert c.scheduler_info()["address"] == cluster.scheduler_address
        c.close()


# ------------------------------------------------------------------------------------------------------------
# private local clusters

def test_dashboard_only_when_asked_and_on_localhost(monkeypatch):
    """``--dashboard`` (here without bokeh, which only changes the page served): the dashboard's HTTP server
    listens, on 127.0.0.1 only."""
    import types

    import psutil

    monkeypatch.setitem(sys.modules, "bokeh", types.ModuleType("bokeh"))    # passes the "needs bokeh" check
    me = psutil.Process()
    before = {p.pid for p in me.children(recursive=True)}
    old = set(_listening([me.pid]))
    with client_for(workers=1, dashboard=True) as c:
        kids = [p.pid for p in me.children(recursive=True) if p.pid not in before]
        socks = [s for s in _listening([me.pid]) if s not in old] + _listening(kids)
        link = c.dashboard_link
        port = int(link.split("//", 1)[1].split("/", 1)[0].rsplit(":", 1)[1])
        assert link.startswith("http://127.0.0.1:") and _speaks_http(port)
    assert {ip for _, ip, _ in socks} == {"127.0.0.1"}, socks
    assert port in {p for _, _, p in socks}


def test_ctrl_c_is_one_line_exit_130_and_the_cluster_is_private(tmp_path, pkgs):
    """Ctrl-C (SIGINT to the command's process group, as a terminal sends it) while members run: one line, exit
    130, no traceback from the command or its workers. While it runs, the local cluster is private: every listening
    socket of the command and its worker processes is on 127.0.0.1 (what ``ss -ltnp`` would show), none
    serves HTTP (no dashboard, no worker metrics), and the workers' stderr goes to OUT/ensemble.log."""
    import psutil

    spec = tmp_path / "s.toml"
    spec.write_text('[ensemble]\nprotocol = "sleepy"\n[base]\nsleep_s = 120\n[axes]\nseed = [1, 2, 3]\n')
    out = tmp_path / "o"
    p = _dnarod(["ensemble", str(spec), "-o", str(out), "--workers", "1"], _env(pkgs))
    try:
        assert _wait_for(out, "members/*/started", p), p.communicate(timeout=30)
        procs = [p.pid] + [c.pid for c in psutil.Process(p.pid).children(recursive=True)]
        socks = _listening(procs)
        http = [port for _, _, port in socks if _speaks_http(port)]
        os.killpg(p.pid, signal.SIGINT)
        t0 = time.perf_counter()
        stdout, stderr = p.communicate(timeout=60)
        took = time.perf_counter() - t0
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
    assert p.returncode == 130, stderr
    _no_noise(stderr)
    said = [ln for ln in stderr.splitlines() if ln.startswith("dnarod:")]
    assert len(said) == 1 and said[0].startswith("dnarod: interrupted;"), stderr
    assert took < 30, took
    assert socks and {ip for _, ip, _ in socks} == {"127.0.0.1"}, socks
    assert len(socks) == 3 and not http, socks              # scheduler, nanny, worker: no dashboard
    log = (out / "ensemble.log").read_text()
    assert "a sleepy member started" in log and "a sleepy member started" not in stderr    # the worker's stderr
    assert "distributed." in log                              # dask's log went there
    assert not list(out.glob("members/*/result.json"))      # nothing finished; the rerun resumes


def test_full_disk_during_an_ensemble_is_one_line_without_task_dumps(tmp_path, pkgs):
    """Writes of the members' results fail with ENOSPC (in the workers and in the command): one line, exit 2,
    no dask task dumps on the terminal."""
    spec = tmp_path / "s.toml"
    spec.write_text(NULL_SPEC)
    p = _dnarod(["ensemble", str(spec), "-o", str(tmp_path / "o"), "--workers", "1", "--no-progress"],
                _env(pkgs, DNAROD_TEST_FULL_DISK="1"))
    try:
        stdout, stderr = p.communicate(timeout=120)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
    assert p.returncode == 2, stderr
    _no_noise(stderr)
    said = [ln for ln in stderr.splitlines() if ln.startswith("dnarod:")]
    assert len(said) == 1 and said[0].startswith("dnarod: error:"), stderr
    assert "result.json" in said[0] and "no space left" in said[0], stderr  # the file named
    assert "results" not in stdout


def test_lost_scheduler_is_one_line_exit_2(tmp_path, pkgs):
    """The scheduler (with its worker) killed while members run: one line naming it, exit 2, no traceback."""
    spec = tmp_path / "s.toml"
    spec.write_text('[ensemble]\nprotocol = "sleepy"\n[base]\nsleep_s = 120\n[axes]\nseed = [1, 2]\n')
    cluster = subprocess.Popen(
        [sys.executable, "-c", "import time\nfrom distributed import LocalCluster\n"
         "c = LocalCluster(n_workers=1, threads_per_worker=1, processes=False, host='127.0.0.1', protocol='tcp://', "
         "dashboard_address='127.0.0.1:0')\nprint(c.scheduler_address, flush=True)\ntime.sleep(600)"],
        env=_env(pkgs), stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    p = None
    try:
        address = cluster.stdout.readline().strip()
        assert address.startswith("tcp://127.0.0.1:"), address
        out = tmp_path / "o"
        p = _dnarod(["ensemble", str(spec), "-o", str(out), "--scheduler", address, "--timeout", "3"], _env(pkgs))
        assert _wait_for(out, "members/*/started", p), p.communicate(timeout=30)
        cluster.kill()                                       # SIGKILL: scheduler and worker gone at once
        t0 = time.perf_counter()
        stdout, stderr = p.communicate(timeout=60)
        took = time.perf_counter() - t0
    finally:
        cluster.kill()
        if p is not None and p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
    assert p.returncode == 2, stderr
    _no_noise(stderr)
    said = [ln for ln in stderr.splitlines() if ln.startswith("dnarod:")]
    assert said == [ln for ln in said if ln.startswith(f"dnarod: error: lost the connection to the dask scheduler "
                                                      f"{address}")] and len(said) == 1, stderr
    assert took < 30, took


# ------------------------------------------------------------------------------------------------------------
# a scheduler behind TLS, with certificates made here

def _openssl(*args):
    subprocess.run(["openssl", *args], check=True, capture_output=True)


@pytest.fixture(scope="module")
def certs(tmp_path_factory):
    """A CA, a scheduler/worker certificate and a client certificate signed by it, and an intruder's certificate
    signed by another CA (EC P-256 keys, made with the openssl command)."""
    if shutil.which("openssl") is None:
        pytest.skip("needs the openssl command")
    d = tmp_path_factory.mktemp("tls")
    ec = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"]
    for ca in ("ca", "rogue"):
        _openssl("req", "-x509", *ec, "-keyout", str(d / f"{ca}.key"), "-out", str(d / f"{ca}.pem"), "-days", "2",
                 "-subj", f"/CN=dnarod test {ca}")
    for name, ca in (("node", "ca"), ("client", "ca"), ("intruder", "rogue")):
        _openssl("req", "-new", *ec, "-keyout", str(d / f"{name}.key"), "-out", str(d / f"{name}.csr"),
                 "-subj", f"/CN={name}")
        _openssl("x509", "-req", "-in", str(d / f"{name}.csr"), "-CA", str(d / f"{ca}.pem"), "-CAkey",
                 str(d / f"{ca}.key"), "-CAcreateserial", "-out", str(d / f"{name}.pem"), "-days", "2")
    return d


@pytest.fixture(scope="module")
def tls_scheduler(certs):
    """A scheduler and one worker that accept only TLS connections with certificates of the test CA."""
    from distributed import LocalCluster
    from distributed.security import Security

    node = dict(tls_ca_file=str(certs / "ca.pem"), tls_scheduler_cert=str(certs / "node.pem"),
                tls_scheduler_key=str(certs / "node.key"), tls_worker_cert=str(certs / "node.pem"),
                tls_worker_key=str(certs / "node.key"), tls_client_cert=str(certs / "node.pem"),
                tls_client_key=str(certs / "node.key"))
    cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=False, host="127.0.0.1", protocol="tls://",
                           security=Security(require_encryption=True, **node), dashboard_address="127.0.0.1:0")
    yield cluster.scheduler_address
    cluster.close()


def test_tls_scheduler_with_and_without_certificates(tmp_path, certs, tls_scheduler):
    address = tls_scheduler
    assert address.startswith("tls://127.0.0.1:")
    spec = tmp_path / "s.toml"
    spec.write_text(NULL_SPEC)

    def run(out, *tls):
        return CliRunner().invoke(main, ["ensemble", str(spec), "-o", str(tmp_path / out), "--scheduler", address,
                                         "--timeout", "5", "--no-progress", *tls])

    mine = ["--tls-ca-file", str(certs / "ca.pem"), "--tls-cert", str(certs / "client.pem"), "--tls-key",
            str(certs / "client.key")]
    r = run("ok", *mine)
    assert r.exit_code == 0, r.output
    import pyarrow.parquet as pq

    rows = pq.read_table(tmp_path / "ok" / "results.parquet").to_pylist()
    assert [(row["status"], row["echo_force_pN"]) for row in rows] == [("ok", 1.0), ("ok", 2.0)]
    import dask                                       # the same certificates from dask's own configuration

    with dask.config.set({"distributed.comm.tls.ca-file": str(certs / "ca.pem"),
                          "distributed.comm.tls.client.cert": str(certs / "client.pem"),
                          "distributed.comm.tls.client.key": str(certs / "client.key")}):
        r = run("ok-config")
    assert r.exit_code == 0, r.output
    assert pq.read_table(tmp_path / "ok-config" / "results.parquet").to_pylist() == rows

    refused = {
        "none": ([], "a tls:// scheduler needs certificates"),
        "intruder": (["--tls-ca-file", str(certs / "ca.pem"), "--tls-cert", str(certs / "intruder.pem"),
                      "--tls-key", str(certs / "intruder.key")], "the scheduler refused this client's certificate"),
        "other-ca": (["--tls-ca-file", str(certs / "rogue.pem"), *mine[2:]],
                     "the scheduler's certificate is not signed by the CA given"),
        "key-mismatch": ([*mine[:4], "--tls-key", str(certs / "intruder.key")], "the key does not match"),
    }
    for name, (tls, words) in refused.items():
        r = run(name, *tls)
        assert r.exit_code == 2, (name, r.output)
        lines = r.output.splitlines()
        assert len(lines) == 1 and lines[0].startswith("dnarod: error: ") and words in lines[0], (name, r.output)
        assert not (tmp_path / name).exists()
    # the TLS port given as tcp://, and a plain scheduler given as tls://: named
    plain = "tcp://" + address.split("://")[1]
    with pytest.raises(SchedulerError, match="found a TLS server .*write tls://"):
        connect(plain, timeout=2)


def test_tls_address_of_a_plain_scheduler_is_named(certs):
    from distributed import LocalCluster

    from dnarod.workflows.ensemble.cluster import tls_security

    sec = tls_security(str(certs / "ca.pem"), str(certs / "client.pem"), str(certs / "client.key"))
    with LocalCluster(n_workers=0, processes=False, host="127.0.0.1", protocol="tcp://",
                      dashboard_address="127.0.0.1:0") as cluster:
        hostport = cluster.scheduler_address.split("://")[1]
        with pytest.raises(SchedulerError, match=rf"not a TLS server; found a dask scheduler without TLS \(write "
                                                 rf"tcp://{hostport}\)"):
            connect(f"tls://{hostport}", timeout=3, security=sec)
        with pytest.raises(SchedulerError, match=rf"the address is tcp://; write tls://{hostport}"):
            connect(f"tcp://{hostport}", timeout=3, security=sec)


# ------------------------------------------------------------------------------------------------------------
# protocols: the registry or an entry point, never an import

def test_spec_protocol_is_never_imported_by_name(tmp_path, monkeypatch):
    mod = "dnarod_spec_import_probe"
    (tmp_path / f"{mod}.py").write_text(f"open({str(tmp_path / 'imported')!r}, 'w').close()\nX = object()\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    for name in (f"{mod}:X", "os:system", "nope"):
        with pytest.raises(SpecError, match=rf"protocol '{name}': not a registered name; known protocols: .*null"):
            resolve_protocol(name)
    assert mod not in sys.modules and not (tmp_path / "imported").exists()
    spec = tmp_path / "s.toml"
    for name in ("os:system", f"{mod}:X"):
        spec.write_text(f'[ensemble]\nprotocol = "{name}"\n[base]\nsource = "ACGTACGTAC"\ntime_ns = 0.001\n')
        r = CliRunner().invoke(main, ["ensemble", str(spec), "-o", str(tmp_path / "o"), "--workers", "0"])
        assert r.exit_code == 2, r.output
        lines = r.output.splitlines()
        assert len(lines) == 1 and "not a registered name; known protocols:" in lines[0], r.output
        assert "magnetic-tweezers" in lines[0] and "null" in lines[0]
    assert mod not in sys.modules and not (tmp_path / "imported").exists() and not (tmp_path / "o").exists()


def test_registered_names_entry_points_and_old_spellings():
    import dnarod.workflows.protocols as protocols

    for name in ("force-extension", "magnetic-tweezers", "torque-turns", "rings", "null"):
        assert name in known_protocols()
    assert resolve_protocol("magnetic-tweezers") is protocols.MAGNETIC_TWEEZERS
    assert resolve_protocol("dnarod.workflows.protocols:MAGNETIC_TWEEZERS") is protocols.MAGNETIC_TWEEZERS
    assert resolve_protocol("dnarod.workflows.ensemble.protocol:NULL") is resolve_protocol("null")
    # dnarod declares its protocols as entry points too (pyproject.toml): found without the registry
    from importlib.metadata import entry_points

    eps = {ep.name: ep.value for ep in entry_points(group="dnarod.protocols")}
    assert eps.get("rings") == "dnarod.workflows.protocols:RINGS", "reinstall dnarod (pip install -e .)"
    with pytest.raises(TypeError, match="give the protocol object"):
        from dnarod.workflows.ensemble.protocol import register_protocol

        register_protocol("x", "os:system")


def test_entry_point_protocol_of_another_package(tmp_path, pkgs, monkeypatch):
    """A package that declares ``sleepy = dnarod_testproto:SLEEPY`` in the group dnarod.protocols: a spec names it
    (its members also run on local and remote clusters in the Ctrl-C and lost-scheduler tests above)."""
    from dnarod.workflows.ensemble import Ensemble

    monkeypatch.syspath_prepend(str(pkgs))
    assert "sleepy" in known_protocols()
    doc = {"ensemble": {"protocol": "sleepy"}, "base": {"sleep_s": 0.01}, "axes": {"seed": [1, 2]}}
    ens = Ensemble.from_dict(doc, tmp_path / "o").run(workers=0, progress=False)
    assert [(r["status"], r["slept_s"]) for r in ens.results().to_pylist()] == [("ok", 0.01), ("ok", 0.01)]
