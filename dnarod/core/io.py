"""Small file helpers shared by every writer: atomic writes, output-path checks, JSON-safe values."""
from __future__ import annotations

import contextlib
import json
import os
import tempfile
from pathlib import Path

import numpy as np

from dnarod.core.errors import DnarodError, ParameterError


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path beside ``path``; on success rename it onto ``path``.

    Readers never see a half-written file: either the old file or the complete new one.
    On an exception the temporary file is removed and ``path`` is untouched.
    """
    path = Path(path)
    bad = _first_file_component(path.parent)
    if bad is not None:
        raise DnarodError(f"cannot write {path}: {bad} is a regular file, not a folder; choose another path")
    ensure_dir(path.parent, what=f"folder of {path}")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:  # name the file asked for, not the temporary one (/proc, a read-only disk, ...)
        raise DnarodError(f"cannot write {path}: no file can be created in {path.parent} ({exc.strerror or exc}); "
                          f"choose another path") from None
    os.close(fd)
    try:
        yield tmp
        # mkstemp creates 0600 files; give the output the mode open() would (0666 minus the umask).
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_text_atomic(path, text):
    """Write a text file atomically."""
    with atomic_path(path) as tmp:
        Path(tmp).write_text(text)


def _first_file_component(path):
    """The first existing ancestor of ``path`` (or itself) that is not a directory, or None."""
    p = Path(path).absolute()
    for anc in [*reversed(p.parents), p]:
        if anc.exists() and not anc.is_dir():
            return anc
        if not anc.exists():
            return None
    return None


def check_dir_path(path, what="output folder"):
    """Raise DnarodError if ``path`` or a parent is an existing regular file (nothing is created)."""
    path = Path(path)
    bad = _first_file_component(path)
    if bad is not None:
        where = "is" if bad == path.absolute() else f"is under {bad}, which is"
        raise DnarodError(f"{what} {path} {where} a regular file, not a folder; choose another path")
    return path


def ensure_dir(path, what="output folder"):
    """Create directory ``path`` (and parents); a clear error when a component is a regular file.

    Raises
    ------
    DnarodError
        ``path`` or one of its parents is an existing regular file, or it cannot be created.
    """
    path = check_dir_path(path, what)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DnarodError(f"{what} {path}: cannot create it ({exc.strerror or exc})") from None
    return path


def file_kind(path):
    """What the first bytes of ``path`` say it is, in words ("a dnarod .dtraj trajectory", "a PDB or other
    text file", "binary data", ...), for messages about a file given where another kind was expected.
    None if it cannot be read."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(512)
    except OSError:
        return None
    if not head:
        return "an empty file"
    if head.startswith(b"PK\x03\x04"):
        return "a zip/.npz archive"
    if head.startswith(b"DTRAJ"):
        return "a dnarod .dtraj trajectory"
    if head.startswith(b"\x1f\x8b"):
        return "a gzip file"
    if head.startswith(b"\x93NUMPY"):
        return "a single numpy array (.npy)"
    text = head.lstrip()
    if text.startswith((b"{", b"[")):
        return "a JSON text file"
    if text.startswith(b"data_"):
        return "an mmCIF text file"
    if text[:6].rstrip() in (b"HEADER", b"ATOM", b"HETATM", b"REMARK", b"CRYST1", b"MODEL", b"TITLE", b"COMPND"):
        return "a PDB text file"
    if b"\0" in head or sum(1 for b in head if b < 9 or 13 < b < 32) > 0.05 * len(head):
        return "binary data"
    return "a text file"


#: Name of the lock file a writer holds in its output folder while it writes (see :func:`folder_lock`).
LOCK_NAME = ".dnarod.lock"


@contextlib.contextmanager
def folder_lock(folder, what="output folder"):
    """Hold an exclusive lock on ``folder`` (created if needed) while the body writes into it.

    A second dnarod process writing into the same folder (two runs with the same ``-o``, a resume while
    the run still goes on, two protocol or validation commands into one folder) is refused at once instead
    of interleaving its files with the first one's. The lock is ``fcntl.flock`` on ``folder/.dnarod.lock``
    (holding the owner's pid and host), released by the operating system if the process dies; the file is
    removed when the body ends (normally or by an exception). A lock file left by a process that was killed
    (``kill -9``, a crash of the machine) is taken over with a one-line notice (a :class:`RuntimeWarning`
    naming its pid; on the command line ``dnarod: warning: ...``).

    Raises
    ------
    DnarodError
        Another process holds the lock (the message names its pid when known).
    """
    folder = ensure_dir(folder, what)
    path = folder / LOCK_NAME
    fh, previous = _take_lock(path)
    if fh is None:
        who = f" (pid {previous.split()[0]})" if previous and previous.split()[0].isdigit() else ""
        raise DnarodError(f"{what} {folder} is in use by another dnarod process{who}: wait for it to finish, or "
                          f"choose another folder with -o")
    try:
        if previous:
            import warnings

            warnings.warn(f"{folder}: took over the lock left by {_describe_owner(previous)}, which ended without "
                          f"releasing it (killed?); its files are kept", RuntimeWarning, stacklevel=3)
        fh.seek(0)
        fh.truncate()
        fh.write(f"{os.getpid()} {_hostname()}\n")
        fh.flush()
        yield folder
    finally:
        import fcntl

        with contextlib.suppress(OSError):
            if _same_file(fh, path):  # ours still: remove it while holding the lock (see _take_lock)
                path.unlink()
        fcntl.flock(fh, fcntl.LOCK_UN)
        fh.close()


def _take_lock(path):
    """``(open file holding the flock, text the lock file held before)``, or ``(None, its text)`` when another
    process holds it. A holder removes the file before releasing the lock, so a lock won on a file that is no
    longer at ``path`` is a lock on nothing: it is dropped and taken again on the new file."""
    import fcntl

    for _ in range(100):
        fh = open(path, "a+")
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.seek(0)
            owner = fh.read().strip()
            fh.close()
            return None, owner
        if _same_file(fh, path):
            fh.seek(0)
            return fh, fh.read().strip()
        fcntl.flock(fh, fcntl.LOCK_UN)
        fh.close()
    raise DnarodError(f"{path}: the lock file keeps being replaced by other processes; try again")


def _same_file(fh, path):
    """True if the open file ``fh`` is the file at ``path`` (not one removed from under it)."""
    try:
        a, b = os.fstat(fh.fileno()), os.stat(path)
    except OSError:
        return False
    return (a.st_dev, a.st_ino) == (b.st_dev, b.st_ino)


def _hostname():
    import socket

    return socket.gethostname()


def _describe_owner(text):
    """Words for the owner recorded in a lock file (``"PID HOST"``): whether it still runs, if on this host."""
    parts = text.split()
    if not parts or not parts[0].isdigit():
        return "an earlier process"
    pid, host = int(parts[0]), parts[1] if len(parts) > 1 else None
    if host is not None and host != _hostname():
        return f"pid {pid} on host {host}"
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return f"pid {pid} (no longer running)"
    except OSError:
        pass
    return f"pid {pid}"


def _a(word):
    return ("an " if word[:1].lower() in "aeiou" else "a ") + word


def check_output_folder(folder, mine, kind, what="output folder"):
    """Refuse to write a ``kind`` into an existing folder that is not empty and holds none of ``mine`` (the names
    that mark a ``kind`` folder): ``-o /``, ``-o ~``, a project folder, another command's output. The lock file
    (:data:`LOCK_NAME`) does not count. Nothing is created.

    Parameters
    ----------
    folder : str or Path
    mine : iterable of str
        File or folder names, any one of which marks ``folder`` as a ``kind`` folder.
    kind : str
        What the command writes, in words ("run", "protocol", "validation report").
    what : str
        The folder's role in messages.

    Returns
    -------
    bool
        True if ``folder`` holds one of ``mine`` (the writer's own rules for an earlier result then apply).

    Raises
    ------
    ParameterError
        One line naming the folder and the first entries it holds.
    """
    folder = check_dir_path(folder, what)
    if not folder.is_dir():
        return False
    if any((folder / m).exists() for m in mine):
        return True
    entries = sorted(p.name for p in folder.iterdir() if p.name != LOCK_NAME)
    if not entries:
        return False
    shown = ", ".join(entries[:4]) + (f", ... ({len(entries)} entries)" if len(entries) > 4 else "")
    raise ParameterError(f"{folder}: not {_a(kind)} folder and not empty (it holds {shown}); choose a new or empty -o "
                      f"folder")


def check_output_file(path, overwrite=False, what="output file"):
    """Check that ``path`` can be written: its folder is creatable and it is not overwritten by accident.

    Raises
    ------
    DnarodError
        A parent is a regular file, ``path`` is a folder, or ``path`` exists and ``overwrite`` is false.
    """
    path = Path(path)
    ensure_dir(path.parent, what=f"folder of the {what}")
    if path.is_dir():
        raise DnarodError(f"{what} {path} is a folder; give a file name")
    if path.exists() and not overwrite:
        raise DnarodError(f"{what} {path} already exists; pass --overwrite to replace it or choose another name")
    return path


def jsonable(obj, nonfinite=None):
    """Convert numpy scalars/arrays, tuples and Paths (recursively) to JSON-serialisable objects.

    Parameters
    ----------
    obj : object
    nonfinite : None or "repr"
        What NaN and infinities become: ``None`` (JSON null) or their ``repr`` string.
    """
    import math

    import numpy as np

    if isinstance(obj, dict):
        return {str(k): jsonable(v, nonfinite) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v, nonfinite) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist(), nonfinite)
    if isinstance(obj, (np.bool_, bool)):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, (np.floating, float)):
        x = float(obj)
        return x if math.isfinite(x) else (repr(x) if nonfinite == "repr" else None)
    if isinstance(obj, Path):
        return str(obj)
    return obj


def read_checkpoint(path, fmt, keys):
    """Read a dnarod checkpoint ``.npz``: ``(meta dict, {key: array})``.

    Raises
    ------
    ParameterError
        One line naming the file when it is missing, truncated, not a checkpoint, or of another
        engine (``fmt`` is the expected ``meta["format"]``).
    """
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            arrays = {k: z[k].copy() for k in keys}
    except FileNotFoundError:
        raise ParameterError(f"cannot resume: {path} does not exist (no checkpoint was written); start a new "
                             f"run with --overwrite") from None
    except Exception as exc:  # noqa: BLE001 - BadZipFile, EOFError, KeyError, ValueError, JSON errors, ...
        why = type(exc).__name__ if not str(exc) else str(exc).splitlines()[0][:80]
        raise ParameterError(f"{path}: not a readable dnarod checkpoint ({why}); nothing was changed; start a new "
                             f"run with --overwrite or -o NEWDIR") from None
    if not isinstance(meta, dict) or meta.get("format") != fmt:
        got = meta.get("format") if isinstance(meta, dict) else None
        raise ParameterError(f"{path}: a {got or 'foreign'} file, not a {fmt}; resume with the engine that wrote "
                             f"it or start a new run with --overwrite")
    return meta, arrays


#: The record an ensemble member keeps beside its run files (its result, settings and log): a folder holding them
#: is a run folder too (the run layer runs a member into it).
RESULT = "result.json"
MEMBER = "member.json"
LOG = "member.log"
