"""Small file helpers shared by every writer: atomic writes, output-path checks, JSON-safe values."""
from __future__ import annotations

import contextlib
import errno
import json
import os
import tempfile
from pathlib import Path

import numpy as np

from dnarod.core.errors import DnarodError, ParameterError


#: Why a write failed, in words, for the errno values that are the user's to fix (a full disk, a quota, a
#: read-only or foreign folder, a name the file system refuses): :func:`write_failure` turns them into one line.
WRITE_ERRNOS = {
    errno.ENOSPC: "no space left on its disk",
    errno.EDQUOT: "disk quota exceeded",
    errno.EFBIG: "file too large for the file system or the file-size limit (ulimit -f)",
    errno.EROFS: "the file system is read-only",
    errno.EACCES: "permission denied",
    errno.EPERM: "operation not permitted",
    errno.ENAMETOOLONG: "file name too long for the file system",
    errno.ENOTDIR: "a part of the path is a regular file, not a folder",
    errno.EISDIR: "a folder is in the way",
    errno.ENOENT: "its folder was removed while dnarod wrote into it",
    errno.EIO: "input/output error (a failing disk or a lost network file system)",
    errno.EMFILE: "too many open files",
}
#: Errors of a full disk (the message gives the free space and, where known, the size needed).
FULL_DISK_ERRNOS = (errno.ENOSPC, errno.EDQUOT)
#: Free space below which a writer's failure without an errno (a C library's "write error") is taken for a
#: full disk: a few file-system blocks.
_NEARLY_FULL = 1 << 20


class WriteError(DnarodError):
    """A file could not be written (a full disk, a quota, a read-only folder, a path the writer cannot take).

    Attributes
    ----------
    path : Path
        The file that was to be written (never a temporary name).
    errno : int or None
    free : int or None
        Bytes free on the disk of ``path`` when the write failed.
    needed : int or None
        Bytes the write needed, where known.
    """

    def __init__(self, message, path=None, errno_=None, free=None, needed=None):
        super().__init__(message)
        self.path, self.errno, self.free, self.needed = path, errno_, free, needed


def human_bytes(n):
    """``n`` bytes in words: ``"512 B"``, ``"3.1 kB"``, ``"2.4 MB"``, ``"1.2 GB"`` (powers of 1000)."""
    n = float(n)
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if abs(n) < 1000 or unit == "TB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.3g} {unit}"
        n /= 1000.0
    return f"{n:.3g} TB"


def disk_free(path):
    """Bytes an unprivileged process may still write on the disk holding ``path`` (or its nearest existing
    folder), or None if it cannot be found."""
    p = Path(path).absolute()
    for anc in [p, *p.parents]:
        try:
            st = os.statvfs(anc)
        except OSError:
            continue
        return int(st.f_bavail) * int(st.f_frsize)
    return None


def write_failure(path, exc, needed=None, needed_bound=False, free_at_failure=None, written=None):
    """The one-line :class:`WriteError` for a failed write of ``path`` (or None if ``exc`` is not about writing).

    ``exc`` is an :class:`OSError` (a full disk, a quota, a read-only folder, ... see :data:`WRITE_ERRNOS`), a
    :class:`UnicodeError` (a writer that cannot take the path), or the exception of a C writer that gives no
    errno (mdtraj's ``XTC write error: 7``), which is taken for a full disk when the disk has under 1 MB (or
    under ``needed``) free, and otherwise is not about writing (None: the caller re-raises it).

    Parameters
    ----------
    path : str or Path
        The file the user will look for (not a temporary name).
    exc : BaseException
    needed : int, optional
        Bytes the write needed, where known.
    needed_bound : bool
        ``needed`` is an upper bound (a compressed format), said so in the message.
    free_at_failure : int, optional
        Bytes free when the write failed (before its temporary file was removed), for a C writer's error.
    written : int, optional
        Bytes the failed write had written (its temporary file's size): without ``needed``, the message says
        it needed more.
    """
    path = Path(path)
    if isinstance(exc, WriteError):
        return exc
    free = disk_free(path.parent)
    if free_at_failure is None:
        free_at_failure = free
    code = exc.errno if isinstance(exc, OSError) else None
    if isinstance(exc, UnicodeError):
        why = (f"a writer could not take the characters of the path ({type(exc).__name__}); choose a path of "
               f"ASCII characters")
        return WriteError(f"cannot write {path}: {why}", path, None, free, needed)
    if code not in WRITE_ERRNOS:
        nearly_full = free_at_failure is not None and free_at_failure < max(_NEARLY_FULL, needed or 0)
        if isinstance(exc, OSError) and code is not None:
            return None
        if not nearly_full:
            return None
        code = errno.ENOSPC
    why = WRITE_ERRNOS[code]
    if code in FULL_DISK_ERRNOS or code == errno.EFBIG:
        space = [] if free is None else [f"{human_bytes(free)} free"]
        if needed:
            space.append(f"{'up to' if needed_bound else 'about'} {human_bytes(needed)} needed")
        elif written:
            space.append(f"more than {human_bytes(written)} needed")
        why += f" ({', '.join(space)})" if space else ""
        todo = "free some space or write elsewhere (-o); the files written before are kept"
    elif code in (errno.EROFS, errno.EACCES, errno.EPERM):
        todo = "choose a folder you can write (-o)"
    elif code == errno.ENAMETOOLONG:
        todo = "choose a shorter name"
    else:
        todo = "choose another path"
    return WriteError(f"cannot write {path}: {why}; {todo}", path, code, free, needed)


@contextlib.contextmanager
def writing(path, needed=None):
    """Turn a failed write of ``path`` inside the body into one :class:`WriteError` line (see
    :func:`write_failure`); any other exception passes unchanged. For files written in place (an appended
    stream such as ``trajectory.dtraj``); whole files are written with :func:`atomic_path`."""
    try:
        yield
    except DnarodError:
        raise
    except Exception as exc:  # noqa: BLE001 - mapped only if it is about the write
        err = write_failure(path, exc, needed)
        if err is None:
            raise
        raise err from None


def _temp_name(name, ascii_only=False, suffix=""):
    """Name of a temporary file beside ``name``: hidden, at most 255 bytes (a long ``name`` is cut), ASCII with
    ``ascii_only``. ``suffix`` ends it (a writer that picks its format by the extension)."""
    import secrets

    tag = secrets.token_hex(4)
    if ascii_only:
        stem = "".join(c if c.isascii() and (c.isalnum() or c in "._-") else "_" for c in name)
    else:
        stem = name
    room = 255 - len(f"..{tag}.tmp{suffix}".encode())
    stem_b = stem.encode("utf-8", "surrogateescape")[:max(room, 0)]
    stem = stem_b.decode("utf-8", "ignore")
    return f".{stem}.{tag}.tmp{suffix}"


@contextlib.contextmanager
def _ascii_folder(folder):
    """An ASCII path naming ``folder`` for a C writer that cannot encode another (mdtraj's XTC writer): the
    folder itself if its path is ASCII, else ``/proc/self/fd/N`` of an open descriptor of it (Linux), else a
    symbolic link in the system's temporary folder (removed afterwards)."""
    folder = Path(folder).absolute()
    if str(folder).isascii():
        yield folder
        return
    fd = None
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    try:
        if fd is not None and Path(f"/proc/self/fd/{fd}").is_dir():
            yield Path(f"/proc/self/fd/{fd}")
            return
        link_dir = Path(tempfile.mkdtemp(prefix="dnarod-"))
        try:
            link = link_dir / "d"
            os.symlink(folder, link)
            yield link
        finally:
            import shutil

            shutil.rmtree(link_dir, ignore_errors=True)
    finally:
        if fd is not None:
            os.close(fd)


@contextlib.contextmanager
def ascii_alias(*paths):
    """ASCII paths (str) naming the existing files ``paths``, for a C reader that cannot take others (mdtraj's
    XTC and DCD readers): a path that is ASCII already is given as is; others are reached through symbolic links,
    with the same extension, in a temporary folder removed afterwards. ``None`` stays ``None``."""
    if all(p is None or str(p).isascii() for p in paths):
        yield [None if p is None else str(p) for p in paths]
        return
    import shutil

    folder = Path(tempfile.mkdtemp(prefix="dnarod-"))
    try:
        out = []
        for i, p in enumerate(paths):
            if p is None or str(p).isascii():
                out.append(None if p is None else str(p))
                continue
            suffix = "".join(c for c in Path(p).suffix if c.isascii())
            link = folder / f"f{i}{suffix}"
            os.symlink(Path(p).absolute(), link)
            out.append(str(link))
        yield out
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@contextlib.contextmanager
def atomic_path(path, needed=None, ascii=False, suffix="", needed_bound=False):
    """Yield a temporary path beside ``path``; on success rename it onto ``path``.

    The one way dnarod writes a whole file: readers never see a half-written file, only the old file or the
    complete new one. On any exception the temporary file is removed and ``path`` is untouched; a failed write
    (a full disk, a quota, a read-only folder, a writer that cannot take the path, a C writer's error on a full
    disk) becomes one :class:`WriteError` line naming ``path`` (:func:`write_failure`), other exceptions pass
    unchanged. The temporary name is hidden and fits the file system's 255 bytes however long ``path``'s name is.

    Parameters
    ----------
    path : str or Path
    needed : int, optional
        Bytes the file will take, where known (given in the message of a full disk).
    needed_bound : bool
        ``needed`` is an upper bound (said so in the message).
    ascii : bool
        Yield a path of ASCII characters (for a writer that cannot take others: mdtraj's XTC writer).
    suffix : str
        End the temporary name with it (a writer that picks its format from the extension).
    """
    path = Path(path)
    bad = _first_file_component(path.parent)
    if bad is not None:
        raise DnarodError(f"cannot write {path}: {bad} is a regular file, not a folder; choose another path")
    ensure_dir(path.parent, what=f"folder of {path}")
    name = _temp_name(path.name, ascii, suffix)
    try:
        fd = os.open(path.parent / name, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except OSError as exc:  # name the file asked for, not the temporary one (/proc, a read-only disk, ...)
        err = write_failure(path, exc, needed, needed_bound)
        if err is not None and exc.errno not in (errno.EACCES, errno.EPERM, errno.EROFS):
            raise err from None
        raise DnarodError(f"cannot write {path}: no file can be created in {path.parent} ({exc.strerror or exc}); "
                          f"choose another path") from None
    os.close(fd)
    tmp = path.parent / name
    try:
        if ascii:
            with _ascii_folder(path.parent) as folder:
                yield str(folder / name)
        else:
            yield str(tmp)
        # mkstemp-like 0600 file; give the output the mode open() would (0666 minus the umask).
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException as exc:
        written = free_then = None
        with contextlib.suppress(OSError):
            written, free_then = os.path.getsize(tmp), disk_free(path.parent)
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, Exception) and not isinstance(exc, DnarodError):
            err = write_failure(path, exc, needed, needed_bound, free_then, written)
            if err is not None:
                raise err from None
        if isinstance(exc, WriteError) and exc.path is not None and Path(exc.path) == tmp:
            raise write_failure(path, OSError(exc.errno, ""), exc.needed or needed, needed_bound) from None
        raise


def write_text_atomic(path, text):
    """Write a text file atomically (UTF-8; :func:`atomic_path`)."""
    data = text.encode("utf-8")
    write_bytes_atomic(path, data)


def write_bytes_atomic(path, data):
    """Write ``data`` to ``path`` atomically (:func:`atomic_path`)."""
    with atomic_path(path, needed=len(data)) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)


def check_free_space(folder, needed, what):
    """Refuse, before any work, to write ``needed`` bytes (an estimate) into ``folder`` if its disk has less free.

    Raises
    ------
    WriteError
        One line naming ``what``, the estimate and the free space.
    """
    free = disk_free(folder)
    if free is None or needed is None or needed <= free:
        return
    raise WriteError(f"{what} needs about {human_bytes(needed)} in {folder}, but its disk has {human_bytes(free)} "
                     f"free; free some space, write elsewhere (-o), or make the output smaller", Path(folder),
                     errno.ENOSPC, free, needed)


#: Hidden folders in which an ``--overwrite`` builds its new output beside the old one (:func:`staged_folder`).
STAGE_PREFIX = ".dnarod-new-"


def _rewrite_message(exc, old, new, tail):
    """Say ``new`` where ``exc``'s message says ``old`` (the hidden folder a replacement was built in), then
    ``tail``."""
    msg = str(exc).replace(str(old) + os.sep, str(new) + os.sep).replace(str(old), str(new))
    exc.args = (msg.rstrip() + tail,) + tuple(exc.args[1:])
    if isinstance(exc, WriteError) and exc.path is not None:
        exc.path = Path(str(exc.path).replace(str(old), str(new)))


def remove_stale_stages(folder):
    """Remove the hidden folders (:data:`STAGE_PREFIX`) left in ``folder`` by an ``--overwrite`` that was killed
    before it finished. Call it while holding ``folder``'s lock (:func:`folder_lock`): a stage of a live writer
    would be removed too."""
    import shutil

    folder = Path(folder)
    if not folder.is_dir():
        return
    for p in folder.iterdir():
        if p.name.startswith(STAGE_PREFIX) and p.is_dir() and not p.is_symlink():
            shutil.rmtree(p, ignore_errors=True)


#: Hidden folders in which a long ``--overwrite`` (an ensemble, a protocol) builds its new output, kept when it
#: stops early so that running the command again continues it (:func:`staged_folder` with ``resume_name``).
REPLACEMENT_PREFIX = ".dnarod-replacement-"


@contextlib.contextmanager
def staged_folder(folder, names, what="output", resume_name=None):
    """Build a replacement of the files ``names`` of ``folder`` beside them, and put it in place only when it
    is complete (the atomic ``--overwrite``).

    Yields a new hidden folder inside ``folder`` (same file system) for the body to write the new output
    into. When the body ends without an exception, every file of the stage is renamed onto its name in
    ``folder`` (renames write no data: a full disk cannot stop them) and the files of ``names`` the new output
    does not have are removed; the stage is removed. When the body raises (a full disk, a blow-up, Ctrl-C),
    the stage is removed and ``folder`` is untouched; a :class:`DnarodError`'s message then names the files
    by their place in ``folder`` and says that the earlier output is unchanged. Hold ``folder``'s lock
    (:func:`folder_lock`) around it.

    Parameters
    ----------
    folder : str or Path
        Holds the earlier output (created if needed).
    names : iterable of str
        The file names an output of this kind consists of (an old one the new output lacks is removed).
    what : str
        The output in words, for messages ("run", "analysis report").
    resume_name : str, optional
        A stage that outlives a failure: ``folder/.dnarod-replacement-<resume_name>`` is kept when the body
        raises, and the same call (the command run again) continues in it (for outputs made of resumable parts:
        a protocol's members). Without it the stage is a fresh hidden folder, removed on failure.
    """
    import shutil

    folder = ensure_dir(folder)
    remove_stale_stages(folder)
    try:
        if resume_name is None:
            stage = Path(tempfile.mkdtemp(prefix=STAGE_PREFIX, dir=folder))
        else:
            stage = folder / f"{REPLACEMENT_PREFIX}{resume_name}"
            stage.mkdir(exist_ok=True)
    except OSError as exc:
        err = write_failure(folder / f"{STAGE_PREFIX}...", exc)
        raise (err or DnarodError(f"cannot create a folder in {folder} ({exc.strerror or exc})")) from None
    try:
        yield stage
    except BaseException as exc:
        if resume_name is None:
            shutil.rmtree(stage, ignore_errors=True)
            tail = f" (the earlier {what} in {folder} is unchanged)"
        else:
            tail = (f" (the earlier {what} in {folder} is unchanged; the same command with --overwrite continues the "
                    f"replacement kept in {stage.name})")
        if isinstance(exc, DnarodError):
            _rewrite_message(exc, stage, folder, tail)
        raise
    try:
        new = sorted(stage.iterdir())
        for p in new:
            dst = folder / p.name
            if dst.is_dir() and not dst.is_symlink():
                shutil.rmtree(dst)
            os.replace(p, dst)
        made = {p.name for p in new}
        for name in set(names) - made:  # a file of the old output the new one does not have (no stale export)
            old = folder / name
            if old.is_dir() and not old.is_symlink():
                shutil.rmtree(old)
            elif old.exists() or old.is_symlink():
                old.unlink()
    finally:
        shutil.rmtree(stage, ignore_errors=True)
        if resume_name is not None:  # replacements begun with other settings and never finished
            for p in folder.glob(f"{REPLACEMENT_PREFIX}*"):
                shutil.rmtree(p, ignore_errors=True)


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
        if exc.errno in FULL_DISK_ERRNOS:
            raise write_failure(path, exc) from None
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
        with contextlib.suppress(OSError):  # the pid is for messages; on a full disk the lock holds without it
            fh.seek(0)
            fh.truncate()
            fh.write(f"{os.getpid()} {_hostname()}\n")
            fh.flush()
        remove_stale_stages(folder)  # left by an --overwrite that was killed: every live stage's writer holds this lock
        yield folder
    finally:
        import fcntl

        with contextlib.suppress(OSError):
            if _same_file(fh, path):  # ours still: remove it while holding the lock (see _take_lock)
                path.unlink()
        fcntl.flock(fh, fcntl.LOCK_UN)
        with contextlib.suppress(OSError):  # a pid that could not be written (a full disk) fails again here
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
    entries = sorted(p.name for p in folder.iterdir() if p.name != LOCK_NAME and not p.name.startswith(".dnarod-"))
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
