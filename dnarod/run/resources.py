"""What a run needs of the machine, checked before any work: memory for the model, words while a large one is set up.

Memory per node: from the peak resident memory of ``dnarod simulate N --time 0.001 --no-export`` at N = 10^4 and
10^5 (the repository's memory benchmark, ``bench_memory``, with its measured table in the benchmark results): a
fixed part (the Python process with numpy, numba, OpenMM) plus a per-node part from the difference, rounded up
(:data:`MEMORY_PER_NODE`), so the estimate errs on the safe side for larger models.
"""
from __future__ import annotations

import os
import sys
import time

from dnarod.core.errors import ParameterError
from dnarod.core.io import human_bytes
from dnarod.core.jit import is_cached

#: Bytes per node of a run's set-up and run (model, normal-mode estimate, engine state, reporters), by engine.
MEMORY_PER_NODE = {"lax": 3500, "openmm": 4500}
#: Bytes of the process before the model (interpreter, numpy, numba, OpenMM).
MEMORY_BASE = 250_000_000
#: Node count from which the set-up prints its stages (about ten seconds of set-up on 2 cores at 10^5 nodes).
LARGE_MODEL = 100_000


def available_memory():
    """Bytes of memory available to a new allocation without swapping (``MemAvailable`` of ``/proc/meminfo``;
    elsewhere the free physical pages, ``os.sysconf``), or None if unknown."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def estimate_memory(n_nodes, engine):
    """Peak memory of a run of ``n_nodes`` nodes with ``engine`` ("lax" or "openmm"), bytes (an estimate)."""
    return MEMORY_BASE + int(n_nodes) * MEMORY_PER_NODE.get(engine, max(MEMORY_PER_NODE.values()))


def check_memory(n_nodes, engine, available=None):
    """Refuse, before any work, a model whose run would need more memory than this machine has available.

    Raises
    ------
    ParameterError
        One line naming the node count, the estimate and the memory available.
    """
    from dnarod.structure.inputs import MAX_NODES

    if n_nodes is None or not 2 <= n_nodes <= MAX_NODES:  # outside: refused by the model's own check, in its words
        return
    need = estimate_memory(n_nodes, engine)
    have = available_memory() if available is None else available
    if have is None or need <= have:
        return
    per = MEMORY_PER_NODE.get(engine, max(MEMORY_PER_NODE.values()))
    most = max(int((have - MEMORY_BASE) // per), 0)
    raise ParameterError(f"a {n_nodes}-node model needs about {human_bytes(need)} of memory with the {engine} engine "
                         f"(~{per / 1000:g} kB per node for set-up and run), but this machine has "
                         f"{human_bytes(have)} available; use at most ~{most} nodes here, or a machine with more "
                         f"memory")


def node_count_hint(source):
    """The node count of a run's SOURCE when it is cheap to know before the model is built (a node count, a
    sequence, a model), else None (a file: its size is checked once the model is built)."""
    from dnarod.core.model import RodModel

    if isinstance(source, RodModel):
        return source.n_nodes
    if isinstance(source, bool):
        return None
    if isinstance(source, int):
        return source
    text = str(source).strip()
    if text.isdigit():
        return int(text)
    if len(text) > 255 or (text and set(text.upper()) <= set("ACGTN") and not os.path.exists(text)):
        return len(text)
    return None


class SetupStages:
    """One line on stderr per stage of a large model's set-up (``dnarod: set-up of N nodes: STAGE...``), with the
    time the previous stage took; silent for small models or when ``enabled`` is false."""

    def __init__(self, n_nodes, enabled=True, stream=None):
        self.on = bool(enabled) and n_nodes is not None and n_nodes >= LARGE_MODEL
        self.n = n_nodes
        self.stream = stream
        self.t = None

    def __call__(self, stage):
        if not self.on:
            return
        now = time.perf_counter()
        if self.t is None:
            self.t = now
        out = self.stream or sys.stderr
        out.write(f"dnarod: set-up of {self.n} nodes, {now - self.t:.0f} s: {stage}...\n")
        out.flush()


#: The entry kernels each engine compiles on its first run (module, function): the inlined helpers are compiled
#: into them.
KERNELS = {
    "common": [("dnarod.physics.modes", "_block_cholesky_ok"), ("dnarod.physics.modes", "_step_hessians"),
               ("dnarod.physics.modes", "_rotate_lab"), ("dnarod.core.strains", "_chain_kernel")],
    "lax": [("dnarod.engines.lax.fast_blocked", "run_steps_blocked"), ("dnarod.engines.lax.fast_blocked", "_scatter"),
            ("dnarod.engines.lax.fast", "compute_loads"), ("dnarod.core.kernels", "chain_loads")],
    "openmm": [],
}
#: Rough first-compile time of each engine's kernels, s (measured as :mod:`dnarod.core.jit` says).
COMPILE_S = {"lax": 70, "openmm": 15}


def uncompiled(engine):
    """Names of the kernels ``engine`` ("lax" or "openmm") would compile on its first call (not in the cache)."""
    out = []
    for mod, name in KERNELS["common"] + KERNELS.get(engine, []):
        try:
            import importlib

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
