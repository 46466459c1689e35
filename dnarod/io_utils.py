"""Small file helpers shared by every writer: atomic writes, output-path checks, JSON-safe values."""
from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path beside ``path``; on success rename it onto ``path``.

    Readers never see a half-written file: either the old file or the complete new one.
    On an exception the temporary file is removed and ``path`` is untouched.
    """
    path = Path(path)
    bad = _first_file_component(path.parent)
    if bad is not None:
        from .errors import DnarodError

        raise DnarodError(f"cannot write {path}: {bad} is a regular file, not a folder; choose another path")
    ensure_dir(path.parent, what=f"folder of {path}")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
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
    from .errors import DnarodError

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
    from .errors import DnarodError

    path = check_dir_path(path, what)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DnarodError(f"{what} {path}: cannot create it ({exc.strerror or exc})") from None
    return path


def check_output_file(path, overwrite=False, what="output file"):
    """Check that ``path`` can be written: its folder is creatable and it is not overwritten by accident.

    Raises
    ------
    DnarodError
        A parent is a regular file, ``path`` is a folder, or ``path`` exists and ``overwrite`` is false.
    """
    from .errors import DnarodError

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
