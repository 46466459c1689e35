"""Where members run: a local dask cluster, an existing scheduler, or SLURM through dask-jobqueue.

Every worker is one process with one thread, and the numerical libraries inside it are held to
one thread (:data:`WORKER_ENV`), so N workers use N cores without oversubscription: OpenMM's CPU
platform reads ``OPENMM_CPU_THREADS`` when it loads, numba ``NUMBA_NUM_THREADS``, BLAS the
``*_NUM_THREADS`` variables.
"""
from __future__ import annotations

import collections
import contextlib
import logging
import os
import socket
import struct
import sys
import time
from pathlib import Path
import traceback
import gc

from dnarod.core.extras import require
from dnarod.core.errors import DnarodError, positive_number

#: Environment of every worker process.
WORKER_ENV = {"OPENMM_CPU_THREADS": "1", "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
              "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "VECLIB_MAXIMUM_THREADS": "1",
              "NUMEXPR_NUM_THREADS": "1"}


class SchedulerError(DnarodError):
    """A scheduler address that does not answer, or a cluster that cannot start."""


def available_cores():
    """Cores this process may use (its CPU affinity, else ``os.cpu_count()``)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


#: Most local worker processes per core: each is a Python process with OpenMM loaded (a few hundred MB), so far
#: more than the cores only fills the memory (the same bound as OpenMM's --threads).
MAX_WORKERS_PER_CORE = 4


def check_workers(workers, option="--workers"):
    """Refuse a local worker count that is not an integer >= 0 or above :data:`MAX_WORKERS_PER_CORE` per core
    (one line naming ``option``); returns it. 0 means: no cluster, members one after another."""
    if workers is None:
        return None
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 0:
        raise SchedulerError(f"{option} {workers!r}: give a number of worker processes >= 0 (0: one after another "
                             f"in this process)")
    most = MAX_WORKERS_PER_CORE * available_cores()
    if workers > most:
        raise SchedulerError(f"{option} {workers}: more than {most} local worker processes ({MAX_WORKERS_PER_CORE} "
                             f"per core here) only fill the memory; use at most {most} (the default is one per core)")
    return workers


#: The interface a local cluster listens on: this machine only (scheduler, nannies, workers and, with
#: ``--dashboard``, the dashboard).
LOCAL_HOST = "127.0.0.1"

#: The dask preload every local worker process runs at start (:mod:`dnarod.workflows.ensemble.worker_setup`).
WORKER_SETUP = "dnarod.workflows.ensemble.worker_setup"


def local_cluster(workers=None, dashboard=False, log=None, **kw):
    """A private :class:`distributed.LocalCluster` of ``workers`` processes (default: the cores), one thread each.

    Private: the scheduler, the nannies and the workers listen on 127.0.0.1 only, and the HTTP servers dask
    starts beside them (the scheduler's, one per worker) are stopped at once unless ``dashboard``, so a local
    ensemble serves nothing over HTTP unless asked. Worker processes ignore SIGINT (Ctrl-C stops the ensemble
    in this process, which then closes the cluster) and, with ``log``, write their stderr (dask's log records)
    to that file from their start.

    Parameters
    ----------
    workers : int, optional
    dashboard : bool
        Serve the dask dashboard on http://127.0.0.1:8787 (the next free port if taken; needs bokeh).
    log : path, optional
        File the worker processes' stderr is appended to (an ensemble's ``ensemble.log``).
    **kw
        Passed to ``LocalCluster`` (``host`` and ``dashboard_address`` replace the private defaults).
    """
    require("distributed", "ensemble")  # one line naming the extra if dask is missing
    import dask
    from distributed import LocalCluster

    from dnarod.workflows.ensemble import worker_setup  # with dask: the workers' set-up

    check_workers(workers)
    n = int(workers or available_cores())
    if dashboard:
        try:
            import bokeh  # noqa: F401
        except ImportError:
            raise SchedulerError("--dashboard needs bokeh (pip install 'bokeh>=3.1')") from None
    if n < 1:
        raise SchedulerError(f"--workers {workers}: need at least 1 worker")
    kw.setdefault("host", LOCAL_HOST)
    kw.setdefault("dashboard_address", f"{LOCAL_HOST}:8787" if dashboard else f"{LOCAL_HOST}:0")
    kw.setdefault("scheduler_kwargs", {"dashboard": bool(dashboard)})
    env = dict(WORKER_ENV, **{worker_setup.ENV_HTTP: "1" if dashboard else "0"})
    if log is not None:
        env[worker_setup.ENV_LOG] = str(Path(log).resolve())
    # the user's own worker preloads (dask configuration) run too, before ours
    preload = list(dask.config.get("distributed.worker.preload", None) or [])
    argv = list(dask.config.get("distributed.worker.preload-argv", None) or [])
    if argv and isinstance(argv[0], str):
        argv = [argv] * len(preload)
    argv = (argv + [[]] * len(preload))[:len(preload)]
    before = _cluster_instances()
    try:
        with _stderr_to(log):       # worker processes inherit it: their stderr is the log from birth
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, env=env,
                                   silence_logs=kw.pop("silence_logs", logging.WARNING if log else logging.ERROR),
                                   preload=preload + [WORKER_SETUP], preload_argv=argv + [[]], **kw)
        if not dashboard:
            cluster.sync(_stop_http, cluster.scheduler)
    except BaseException:
        # a cluster half-started when Ctrl-C came: dask's exit hook would fail to close it, with a traceback;
        # its worker processes end with this process
        _forget_clusters(before)
        raise
    return cluster


async def _stop_http(server):
    """Stop the HTTP server dask starts beside a scheduler or worker (its dashboard and metrics)."""
    http = getattr(server, "http_server", None)
    if http is not None:
        http.stop()


def _cluster_instances():
    try:
        from distributed.deploy.spec import SpecCluster

        return set(SpecCluster._instances)
    except (ImportError, AttributeError):
        return set()


def _forget_clusters(before):
    try:
        from distributed.deploy.spec import SpecCluster

        for c in set(SpecCluster._instances) - before:
            SpecCluster._instances.discard(c)
    except (ImportError, AttributeError):
        pass


@contextlib.contextmanager
def _stderr_to(path):
    """File descriptor 2 appends to ``path`` inside the block (processes started there keep it); nothing if
    ``path`` is None or cannot be opened."""
    if path is None:
        yield
        return
    try:
        fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    except OSError:
        yield
        return
    with contextlib.suppress(Exception):
        sys.stderr.flush()
    saved = os.dup(2)
    os.dup2(fd, 2)
    os.close(fd)
    try:
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


# ------------------------------------------------------------------------------------------------------------
# dask's own log records: to the ensemble's log file, never to the terminal

#: Loggers whose records are dask's (and its event loop's), not dnarod's.
DASK_LOGGERS = ("distributed", "tornado", "bokeh", "asyncio")


class DaskLog(logging.Handler):
    """Dask's log records, held in memory until ``open`` names a file and appended there from then on.

    A record that cannot be written (a full disk) is dropped without a word: the command reports the fault
    itself, in one line.
    """

    def __init__(self, held=10000):
        super().__init__()
        self.setFormatter(logging.Formatter("%(asctime)s pid %(process)d %(levelname)s %(name)s: %(message)s"))
        self._held = collections.deque(maxlen=held)
        self._stream = None
        self.path = None

    def open(self, path):
        """Append to ``path`` from now on (with the records held so far)."""
        self.acquire()
        try:
            self._close_stream()
            try:
                self._stream = open(path, "a", encoding="utf-8", errors="replace")
                self.path = Path(path)
            except OSError:
                return
            while self._held:
                self._write(self._held.popleft())
        finally:
            self.release()

    def emit(self, record):
        try:
            msg = self.format(record)
        except Exception:  # noqa: BLE001 -- a record dask could not format is not worth a traceback
            return
        if self._stream is None:
            self._held.append(msg)
        else:
            self._write(msg)

    def unraisable(self, unraisable):
        """A ``sys.unraisablehook``: exceptions Python cannot raise (dask's exit hooks, ``__del__``) go to the
        log too."""
        exc = unraisable.exc_value
        text = "".join(traceback.format_exception(type(exc), exc, unraisable.exc_traceback)) if exc else ""
        self.emit(logging.makeLogRecord({"name": "unraisable", "levelno": logging.WARNING, "levelname": "WARNING",
                                         "msg": f"{unraisable.err_msg or 'Exception ignored'}: "
                                                f"{unraisable.object!r}\n{text}".rstrip()}))

    def _write(self, msg):
        try:
            self._stream.write(msg + "\n")
            self._stream.flush()
        except (OSError, ValueError):
            pass

    def _close_stream(self):
        if self._stream is not None:
            with contextlib.suppress(OSError, ValueError):
                self._stream.close()
            self._stream = None

    def handleError(self, record):
        pass

    def close(self):
        self.acquire()
        try:
            self._close_stream()
        finally:
            self.release()
        super().close()


def route_dask_logs(handler):
    """Send the records of :data:`DASK_LOGGERS` (and of their children with handlers of their own) to ``handler``
    only; returns a function that puts the loggers back as they were."""
    import distributed  # noqa: F401 -- its import sets up its loggers (handlers on stderr): replace them after it

    saved = []
    names = set(DASK_LOGGERS) | {n for n in logging.root.manager.loggerDict
                                 if n.split(".")[0] in DASK_LOGGERS}
    for name in sorted(names):
        lg = logging.getLogger(name)
        if name not in DASK_LOGGERS and not lg.handlers:
            continue        # its records reach a parent's handler
        saved.append((lg, list(lg.handlers), lg.propagate))
        for h in list(lg.handlers):
            lg.removeHandler(h)
        lg.addHandler(handler)
        lg.propagate = False

    def restore():
        for lg, handlers, propagate in saved:
            lg.removeHandler(handler)
            for h in handlers:
                lg.addHandler(h)
            lg.propagate = propagate

    return restore


@contextlib.contextmanager
def dask_logs(path=None):
    """Inside the block, dask's log records go to ``path`` (appended; held in memory until a path is given with
    the handler's :meth:`DaskLog.open`), never to the terminal. Yields the :class:`DaskLog`."""
    handler = DaskLog()
    if path is not None:
        handler.open(path)
    restore = route_dask_logs(handler)
    try:
        yield handler
    finally:
        restore()
        handler.close()


# ------------------------------------------------------------------------------------------------------------
# a scheduler given by address: look first, then connect

#: The ports dask uses by default (scheduler, dashboard).
SCHEDULER_PORT, DASHBOARD_PORT = 8786, 8787


def split_address(address):
    """``(scheme, host, port)`` of a scheduler address (``tcp://HOST:PORT``, ``tls://HOST:PORT`` or ``HOST:PORT``,
    whose scheme is dask's ``distributed.comm.default-scheme``)."""
    from distributed.comm.addressing import parse_address, parse_host_port

    try:
        scheme, loc = parse_address(str(address))
        host, port = parse_host_port(loc)
        port = int(port)
    except (ValueError, TypeError):
        raise SchedulerError(f"--scheduler {address}: not a scheduler address; write tcp://HOST:PORT (e.g. "
                             f"tcp://127.0.0.1:{SCHEDULER_PORT}) or tls://HOST:PORT") from None
    if scheme not in ("tcp", "tls"):
        raise SchedulerError(f"--scheduler {address}: dnarod connects to tcp:// or tls:// schedulers, not "
                             f"{scheme}://")
    if not 0 < port < 65536:
        raise SchedulerError(f"--scheduler {address}: port {port} is not a port (1-65535)")
    return scheme, host, port


def tls_security(ca_file=None, cert=None, key=None):
    """The :class:`distributed.security.Security` of a client: the files given, the rest from dask's configuration
    (``distributed.comm.tls.ca-file``, ``distributed.comm.tls.client.cert`` and ``.key``).

    Returns None when neither names a certificate. Raises :class:`SchedulerError` (one line) for a file that
    cannot be read, a CA without a client certificate (or the reverse), or files that are not a matching
    PEM certificate and key.
    """
    import ssl  # only for TLS clusters: not at the CLI's start-up

    from distributed.security import Security

    given = {"tls_ca_file": ("--tls-ca-file", ca_file), "tls_client_cert": ("--tls-cert", cert),
             "tls_client_key": ("--tls-key", key)}
    for option, path in given.values():
        if path is not None and not os.path.isfile(path):
            raise SchedulerError(f"{option} {path}: no such file")
    kw = {field: path for field, (_, path) in given.items() if path is not None}
    try:
        sec = Security(**kw)
    except (ValueError, TypeError, ImportError) as exc:
        raise SchedulerError(f"dask's TLS configuration: {_one_line(exc)}") from None
    if not (sec.tls_ca_file or sec.tls_client_cert or sec.tls_client_key):
        return None
    if not (sec.tls_ca_file and sec.tls_client_cert):
        missing = "the CA certificate (--tls-ca-file)" if not sec.tls_ca_file else \
            "this client's certificate (--tls-cert, and --tls-key unless the key is in the same file)"
        raise SchedulerError(f"TLS needs the CA that signed the scheduler's certificate and a client certificate "
                             f"signed by it; {missing} is missing (or set distributed.comm.tls.* in dask's "
                             f"configuration)")
    files = ", ".join(str(p) for p in (sec.tls_ca_file, sec.tls_client_cert, sec.tls_client_key) if p)
    try:
        sec.get_connection_args("client")
    except (ssl.SSLError, OSError, ValueError) as exc:
        raise SchedulerError(f"TLS files {files}: {_one_line(exc)} (not PEM, or the key does not match the "
                             f"certificate?)") from None
    return sec


def _one_line(exc):
    msg = " ".join(str(exc).split()) or type(exc).__name__
    return msg if len(msg) <= 200 else msg[:200] + "..."


def _looks_like_dask(data):
    """Whether ``data`` (what a server sent first) starts like dask's handshake: an 8-byte little-endian length
    of a message whose first 8 bytes count its frames."""
    if len(data) < 16:
        return False
    total, n_frames = struct.unpack("<QQ", data[:16])
    return 16 <= total <= 1 << 20 and 1 <= n_frames <= 256


def _describe(data):
    """What a server that sent ``data`` first is: a phrase completing "found ..."."""
    if data.startswith(b"HTTP/"):
        return f"an HTTP server, not a dask scheduler (a dashboard? the scheduler usually listens on port " \
               f"{SCHEDULER_PORT})"
    if data[:1] in (b"\x15", b"\x16") and data[1:2] == b"\x03":
        return "a TLS server (a dask scheduler with TLS? write tls://HOST:PORT and give your certificates)"
    line = data.split(b"\n", 1)[0].strip()[:60]
    if line and all(32 <= c < 127 for c in line):
        what = "an SSH server" if line.startswith(b"SSH-") else "a server"
        return f"{what} that is not a dask scheduler (it said {line.decode()!r})"
    return f"a server that is not a dask scheduler (its first {len(data)} bytes are not dask's handshake)"


def _recv(sock, deadline, want=16):
    """Bytes the peer sends before ``deadline``: at least ``want`` unless it stops; b"" if it closed at once,
    None if it sent nothing in time."""
    data = b""
    while len(data) < want:
        left = deadline - time.monotonic()
        if left <= 0:
            break
        sock.settimeout(left)
        try:
            chunk = sock.recv(4096)
        except (socket.timeout, TimeoutError):
            break
        except ConnectionResetError:
            chunk = b""
        if not chunk:
            return data
        data += chunk
    return data or None


def _open(host, port, deadline, where):
    """A TCP connection to ``host:port``, or :class:`SchedulerError` saying why not."""
    left = max(0.05, deadline - time.monotonic())
    try:
        return socket.create_connection((host, port), timeout=left)
    except socket.gaierror as exc:
        raise SchedulerError(f"{where}: unknown host {host!r} ({exc.strerror}); check the address") from None
    except ConnectionRefusedError:
        hint = (f"; {DASHBOARD_PORT} is the dashboard's port, the scheduler's is usually {SCHEDULER_PORT}"
                if port == DASHBOARD_PORT else "")
        raise SchedulerError(f"{where}: nothing listens on port {port} of {host} (connection refused); start the "
                             f"scheduler (dask scheduler --port {port}) or check the address{hint}") from None
    except (socket.timeout, TimeoutError):
        raise SchedulerError(f"{where}: {host}:{port} did not accept a connection within {left:.3g} s (a host "
                             f"that is down, or a firewall?); check the address and that the scheduler is "
                             f"running") from None
    except OSError as exc:
        raise SchedulerError(f"{where}: cannot reach {host}:{port}: {exc.strerror or _one_line(exc)}") from None


def _http_probe(host, port, deadline):
    """What answers an HTTP request at ``host:port`` (a phrase completing "found ..."), or None."""
    try:
        with socket.create_connection((host, port), timeout=max(0.05, deadline - time.monotonic())) as s:
            s.sendall(f"GET / HTTP/1.0\r\nHost: {host}:{port}\r\n\r\n".encode())
            data = _recv(s, deadline, want=512) or b""
    except OSError:
        return None
    if data.startswith(b"HTTP/"):
        head = data.split(b"\r\n\r\n", 1)[0].lower()
        if b"tornadoserver" in head and b"status" in head:
            return (f"the dask dashboard (an HTTP server), not the scheduler; the scheduler usually listens on "
                    f"port {SCHEDULER_PORT}")
        return _describe(data)
    if data[:1] == b"\x15":
        return _describe(data)
    return None


def _tls_probe(host, port, deadline):
    """Whether a TLS server answers a handshake at ``host:port`` (certificates not checked)."""
    import ssl  # only for TLS clusters: not at the CLI's start-up

    ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    ctx.check_hostname = False
    ctx.verify_mode = ssl.CERT_NONE
    try:
        with socket.create_connection((host, port), timeout=max(0.05, deadline - time.monotonic())) as raw:
            with ctx.wrap_socket(raw):
                return True
    except ssl.SSLError as exc:
        return "ALERT" in str(exc.reason or "").upper()
    except OSError:
        return False


#: SSL error reasons that say the peer does not speak TLS at all.
_NOT_TLS = ("WRONG_VERSION_NUMBER", "RECORD_LAYER_FAILURE", "PACKET_LENGTH_TOO_LONG", "HTTP_REQUEST",
            "UNKNOWN_PROTOCOL", "UNEXPECTED_EOF_WHILE_READING")


def _plain_what(host, port, deadline, where, wait):
    """What listens at ``host:port`` without TLS: None for a dask scheduler, else a phrase completing
    "found ..."."""
    with _open(host, port, deadline, where) as s:
        first = _recv(s, min(deadline, time.monotonic() + wait))
    if first is None:
        what = _http_probe(host, port, deadline)
        if what is None and _tls_probe(host, port, deadline):
            what = _describe(b"\x16\x03")
        return what or (f"a server that accepted the connection but sent nothing in {wait:.3g} s and answers "
                        f"neither HTTP nor TLS; not a dask scheduler (which sends its handshake at once)")
    if first == b"":
        return "a server that closed the connection at once; not a dask scheduler"
    return None if _looks_like_dask(first) else _describe(first)


def probe_scheduler(address, timeout=10.0, security=None):
    """Look at what listens at ``address`` before dask is given it; :class:`SchedulerError` (one line naming the
    address and what was found there) unless it is a dask scheduler.

    A dask scheduler sends its handshake as soon as a connection opens (after the TLS handshake for
    ``tls://``); whatever else answers (nothing, an HTTP server such as the dashboard on port 8787, an SSH
    server, a plain-TCP scheduler given as ``tls://``) is named. Takes at most ``timeout`` seconds.

    Parameters
    ----------
    address : str
        ``tcp://HOST:PORT``, ``tls://HOST:PORT`` or ``HOST:PORT``.
    timeout : float
        Seconds, in all.
    security : distributed.security.Security, optional
        The client's TLS certificates (for ``tls://``).
    """
    import ssl  # only for TLS clusters: not at the CLI's start-up

    scheme, host, port = split_address(address)
    where = f"--scheduler {address}"
    timeout = float(timeout)
    deadline = time.monotonic() + timeout
    wait = max(0.5, timeout / 2)
    if scheme == "tcp":
        what = _plain_what(host, port, deadline, where, wait)
        if what is not None:
            raise SchedulerError(f"{where}: found {what}")
        return
    ctx = security.get_connection_args("client")["ssl_context"]
    raw = _open(host, port, deadline, where)
    try:
        raw.settimeout(max(0.05, deadline - time.monotonic()))
        with ctx.wrap_socket(raw, server_hostname=host) as s:
            first = _recv(s, min(deadline, time.monotonic() + wait))
    except ssl.SSLCertVerificationError as exc:
        raise SchedulerError(f"{where}: the scheduler's certificate is not signed by the CA given "
                             f"({exc.verify_message or exc.reason}); check --tls-ca-file") from None
    except ssl.SSLError as exc:
        reason = str(exc.reason or _one_line(exc))
        if reason.upper() in _NOT_TLS:
            what = _plain_what(host, port, deadline, where, wait)
            what = f"a dask scheduler without TLS (write tcp://{host}:{port})" if what is None else what
            raise SchedulerError(f"{where}: not a TLS server; found {what}") from None
        if "CERTIFICATE" in reason.upper() or "UNKNOWN_CA" in reason.upper():
            raise SchedulerError(f"{where}: the scheduler refused this client's certificate ({reason}); give a "
                                 f"certificate signed by the scheduler's CA (--tls-cert, --tls-key)") from None
        raise SchedulerError(f"{where}: the TLS handshake failed ({reason})") from None
    except (socket.timeout, TimeoutError):
        raise SchedulerError(f"{where}: no TLS handshake within {timeout:g} s (not a TLS server?)") from None
    except OSError as exc:
        raise SchedulerError(f"{where}: the connection failed during the TLS handshake "
                             f"({exc.strerror or _one_line(exc)})") from None
    finally:
        raw.close()
    if first is None:
        raise SchedulerError(f"{where}: found a TLS server that sent nothing in {wait:.3g} s after the handshake; "
                             f"not a dask scheduler (which sends its handshake at once)")
    if first == b"":
        raise SchedulerError(f"{where}: found a TLS server that closed the connection after the handshake (it "
                             f"refused this client's certificate?)")
    if not _looks_like_dask(first):
        raise SchedulerError(f"{where}: found, behind TLS, {_describe(first)}")


def connect(address, timeout=10.0, security=None):
    """A :class:`distributed.Client` of the scheduler at ``address``; one clear line within ``timeout`` s if not.

    The address is looked at first (:func:`probe_scheduler`), so an address where something else listens
    (the dashboard's port, an SSH server) or nothing does is named in one line rather than handed to dask.
    ``tls://`` addresses need ``security`` or dask's TLS configuration (:func:`tls_security`).

    Raises
    ------
    SchedulerError
        Nothing or something other than a dask scheduler answered at ``address`` within ``timeout`` seconds,
        TLS failed, or the address is malformed.
    """
    require("distributed", "ensemble")  # one line naming the extra if dask is missing
    from distributed import Client

    scheme, host, port = split_address(address)
    seconds = positive_number(timeout)
    if seconds is None:
        raise SchedulerError(f"--timeout {timeout}: give the seconds to wait for the scheduler (a number > 0)")
    timeout = seconds
    if scheme == "tls" and security is None:
        security = tls_security()
        if security is None:
            raise SchedulerError(f"--scheduler {address}: a tls:// scheduler needs certificates: give --tls-ca-file, "
                                 f"--tls-cert and --tls-key (or set distributed.comm.tls.ca-file and "
                                 f"distributed.comm.tls.client.cert/key in dask's configuration)")
    if scheme == "tcp" and security is not None and security.require_encryption:
        raise SchedulerError(f"--scheduler {address}: TLS certificates are given (or dask's configuration requires "
                             f"encryption) but the address is tcp://; write tls://{host}:{port}")
    t0 = time.monotonic()
    probe_scheduler(address, timeout, security)
    left = max(1.0, timeout - (time.monotonic() - t0))
    kw = {} if security is None else {"security": security}
    try:
        return Client(address, timeout=f"{left}s", set_as_default=False, **kw)
    except (Exception, MemoryError) as exc:  # noqa: BLE001 -- whatever dask raises, one line
        msg = _one_line(exc)
    # the half-made client's clean-up logs and complains; into dask's log, not the terminal
    _collect_quietly()
    raise SchedulerError(f"--scheduler {address}: no dask scheduler answered within {timeout:g} s ({msg}); "
                         f"check the address and that the scheduler is running")


def _collect_quietly():
    hook = sys.unraisablehook
    sys.unraisablehook = lambda u: logging.getLogger("distributed.client").debug(
        "%s: %r", u.err_msg, u.exc_value)
    try:
        gc.collect()
    finally:
        sys.unraisablehook = hook


@contextlib.contextmanager
def client_for(client=None, scheduler=None, workers=None, timeout=10.0, dashboard=False, security=None, log=None):
    """Yield a client: ``client`` as given, one connected to ``scheduler``, or a new private local cluster's.

    Clients and clusters made here are closed on exit; a given ``client`` is left open. ``security``: TLS
    certificates for ``scheduler`` (:func:`tls_security`); ``log``: the file a local cluster's worker processes
    write their stderr to.
    """
    require("distributed", "ensemble")  # one line naming the extra if dask is missing
    if client is not None:
        yield client
        return
    if scheduler:
        c = connect(scheduler, timeout, security)
        try:
            yield c
        finally:
            _close_quietly(c)
        return
    from distributed import Client

    cluster = local_cluster(workers, dashboard=dashboard, log=log)
    try:
        c = Client(cluster, set_as_default=False)
    except BaseException:
        _close_quietly(cluster)
        raise
    try:
        yield c
    finally:
        _close_quietly(c)
        _close_quietly(cluster)


def _close_quietly(obj):
    """Close a client or cluster; what fails while closing (a lost scheduler) is dask's to log, not ours to raise."""
    try:
        obj.close()
    except Exception as exc:  # noqa: BLE001
        logging.getLogger("distributed").info("closing %s: %s", type(obj).__name__, _one_line(exc))

def slurm_cluster(cores=1, processes=None, memory="4GB", walltime="04:00:00", queue=None, account=None,
                  job_extra_directives=(), python=None, **kw):
    """A :class:`dask_jobqueue.SLURMCluster` whose jobs run one-thread dnarod workers.

    Each SLURM job gets ``cores`` CPUs and starts ``processes`` worker processes (default one
    per core) of one thread each, with :data:`WORKER_ENV` exported in the job script. Scale it
    with ``cluster.scale(jobs=N)`` or ``cluster.adapt(maximum_jobs=N)`` and pass
    ``distributed.Client(cluster)`` to :meth:`~dnarod.workflows.ensemble.ensemble.Ensemble.run`. The ensemble folder
    must be on a
    file system the compute nodes share.

    Parameters
    ----------
    cores : int
        CPUs per job (``#SBATCH --cpus-per-task``).
    processes : int, optional
        Workers per job (default ``cores``).
    memory : str
        Memory per job (``#SBATCH --mem``).
    walltime : str
        ``HH:MM:SS`` per job (``#SBATCH -t``). Members resume across jobs, so short walltimes only
        cost the steps since a member's last checkpoint.
    queue, account : str, optional
        ``#SBATCH -p`` and ``-A``.
    job_extra_directives : sequence of str
        More ``#SBATCH`` lines, e.g. ``["--constraint=skylake"]``.
    python : str, optional
        Python executable on the nodes (default this one).
    **kw
        Passed to ``SLURMCluster``.

    Returns
    -------
    dask_jobqueue.SLURMCluster
    """
    try:
        SLURMCluster = require("dask_jobqueue", "cluster").SLURMCluster
    except ImportError:
        raise SchedulerError("SLURM clusters need dask-jobqueue: pip install 'dnarod[cluster]'") from None

    processes = int(processes or cores)
    prologue = [f"export {k}={v}" for k, v in WORKER_ENV.items()]
    return SLURMCluster(cores=int(cores), processes=processes, memory=memory, walltime=walltime, queue=queue,
                        account=account, job_extra_directives=list(job_extra_directives),
                        job_script_prologue=prologue + list(kw.pop("job_script_prologue", [])),
                        python=python or sys.executable, **kw)
