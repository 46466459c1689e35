"""numba's on-disk cache of the compiled kernels: whether a kernel is in it, and a writable place for it.

Every kernel is compiled with ``@njit(cache=True)``: numba writes the machine code beside the module
(``__pycache__``), or, where the package folder is read-only, into the user's cache folder (numba's own
fallback; ``NUMBA_CACHE_DIR`` overrides both), so the compile happens once per install (and again after the
source changes). The first run after an install compiles them: measured on a 2-core machine with an empty
``NUMBA_CACHE_DIR`` (``dnarod simulate 50 --engine lax --time 0.01``), 72 s for the Lax-form engine (its
time-step kernels, the elastic loads, the normal-mode and strain kernels) and 13 s for the OpenMM engine (the
normal-mode and strain kernels of the set-up); a loaded machine takes longer.
"""
from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

def is_cached(dispatcher):
    """True if numba's disk cache holds compiled code of ``dispatcher`` for its current source, False if not (or
    if it cannot cache: it then compiles in every process), None if this numba does not say."""
    cache = getattr(dispatcher, "_cache", None)
    if cache is None:
        return None
    if type(cache).__name__ == "NullCache":
        return False
    try:
        return bool(cache._cache_file._load_index())
    except Exception:  # noqa: BLE001 - numba's internals changed: unknown
        return None


def _writable(folder):
    """True if a file can be created in ``folder`` (created if needed)."""
    try:
        Path(folder).mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            return True
    except OSError:
        return False


def ensure_numba_cache(package_dir=None, user_dir=None):
    """Make sure numba can cache the kernels (else it refuses every ``cache=True`` kernel at import, or compiles
    them in every process): numba writes beside the package, or, where that is read-only, in the user's cache
    folder; where both are read-only (a system-wide install and a read-only home), ``NUMBA_CACHE_DIR`` is set to a
    folder of this user in the system's temporary folder. A ``NUMBA_CACHE_DIR`` already set is left alone.

    Returns
    -------
    str or None
        The folder set, or None if numba's own choice works.
    """
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    package_dir = Path(__file__).resolve().parents[1] if package_dir is None else Path(package_dir)
    if user_dir is None:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        user_dir = os.path.join(base, "numba")
    if _writable(package_dir / "__pycache__") or _writable(user_dir):
        return None
    folder = os.path.join(tempfile.gettempdir(), f"dnarod-numba-{os.getuid() if hasattr(os, 'getuid') else 'user'}")
    if not _writable(folder):
        return None
    os.environ["NUMBA_CACHE_DIR"] = folder
    cfg = sys.modules.get("numba.core.config")
    if cfg is not None:  # numba read its configuration already
        cfg.CACHE_DIR = folder
    return folder
