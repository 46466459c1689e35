"""Whether numba's compiled kernels are already in its on-disk cache, for a word before a long first compile.

Every kernel is compiled with ``@njit(cache=True)``: numba writes the machine code beside the module
(``__pycache__``), or, where the package folder is read-only, into the user's cache folder (numba's own
fallback; ``NUMBA_CACHE_DIR`` overrides both), so the compile happens once per install (and again after the
source changes). The first run after an install compiles them: measured on a 2-core machine with an empty
``NUMBA_CACHE_DIR`` (``dnarod simulate 50 --engine lax --time 0.01``), 72 s for the Lax-form engine (its
time-step kernels, the elastic loads, the normal-mode and strain kernels) and 13 s for the OpenMM engine (the
normal-mode and strain kernels of the set-up); the issue that asked for this notice saw 157 s on a loaded
machine.
"""
from __future__ import annotations

import importlib

#: The entry kernels each engine compiles on its first run (module, function): the inlined helpers are compiled
#: into them.
KERNELS = {
    "common": [("dnarod.physics.modes", "_block_cholesky_ok"), ("dnarod.physics.modes", "_step_hessians"),
               ("dnarod.physics.modes", "_rotate_lab"), ("dnarod.core.strains", "_chain_kernel")],
    "lax": [("dnarod.engines.lax.fast_blocked", "run_steps_blocked"), ("dnarod.engines.lax.fast_blocked", "_scatter"),
            ("dnarod.engines.lax.fast", "compute_loads"), ("dnarod.core.kernels", "chain_loads")],
    "openmm": [],
}
#: Rough first-compile time of each engine's kernels, s (measured as the module docstring says).
COMPILE_S = {"lax": 70, "openmm": 15}


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


def uncompiled(engine):
    """Names of the kernels ``engine`` ("lax" or "openmm") would compile on its first call (not in the cache)."""
    out = []
    for mod, name in KERNELS["common"] + KERNELS.get(engine, []):
        try:
            disp = getattr(importlib.import_module(mod), name)
        except (ImportError, AttributeError):
            continue
        if is_cached(disp) is False:
            out.append(f"{mod.rsplit('.', 1)[-1]}.{name}")
    return out


def compile_notice(engine):
    """The one-line notice before a first compile, or None when the kernels are cached."""
    missing = uncompiled(engine)
    if not missing:
        return None
    n = COMPILE_S.get(engine, 30)
    return (f"compiling kernels (first run after install, ~{n} s on 2 cores; cached for later runs: "
            f"{len(missing)} kernel{'s' if len(missing) > 1 else ''})...")
