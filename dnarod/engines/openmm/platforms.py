"""Choice of the OpenMM platform (CUDA, OpenCL, CPU, Reference) and its properties.

Automatic choice (``requested=None``), in order:

1. **CUDA** (or HIP) when OpenMM has loaded that plugin (it only loads with a working driver;
   ``pip install 'dnarod[cuda12]'`` brings ``openmm-cuda-12``), with the compiled plugin's device
   kernel where it was built for that platform (:func:`dnarod.engines.openmm.plugin.device_kernel`), else
   the portable elastic path;
2. **OpenCL** when an OpenCL platform offers a *GPU* device (queried through the OpenCL ICD
   loader, without creating an OpenMM Context), with the same elastic choice. A CPU-only OpenCL
   implementation such as pocl is never chosen automatically: it runs several times slower than
   the CPU paths (docs/platforms.md, "The automatic platform choice");
3. **the CPU fast path**: the numba/``PythonForce`` callbacks (or the compiled plugin's kernel) on
   the **Reference** platform, or on the **CPU** platform when more than one thread is asked for
   (``threads`` > 1). The CPU platform runs its integrator on a worker thread even with
   ``Threads=1``, so every step (and every Python callback) is handed between the Python thread
   and the worker; one thread therefore means the Reference platform (a Dask worker's
   ``OPENMM_CPU_THREADS=1`` included). Per CPU-second on one core the Reference platform is
   faster at 10^2-10^3 nodes and tied at 10^4-10^6, where the CPU platform's threaded integrator
   may still gain wall-clock time from idle cores (``--threads``); a 1-kbp tweezers member with the
   compiled plugin, stepped in 20-ps rounds, takes about twice the CPU time on the CPU platform with
   one thread (measurements: docs/platforms.md, "The automatic platform choice").

``requested`` (``--platform``) overrides the choice; the reason of the choice is returned so
the caller can print it.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import functools
import os

import openmm

from dnarod.core.errors import ParameterError
from dnarod.engines.openmm.plugin import device_kernel

#: Largest node count run on the Reference platform by the automatic choice (CPU platform above);
#: None: no limit (Reference is as fast or faster per CPU-second at 10^2-10^6 nodes; docs/platforms.md).
REFERENCE_MAX_NODES = None
#: Platforms that run the numba PythonForce (fast) elastic path without copying off a device.
CALLBACK_PLATFORMS = ("CPU", "Reference")
#: Platforms on GPUs (portable path only).
GPU_PLATFORMS = ("CUDA", "HIP", "OpenCL")
#: Default precision on GPU platforms: forces in single, integration and constraints in double.
DEFAULT_GPU_PRECISION = "mixed"
_CL_DEVICE_TYPE_GPU = 1 << 2


def platform_names():
    """Names of the OpenMM platforms installed and loaded here, e.g. ``["Reference", "CPU", "OpenCL"]``."""
    return [openmm.Platform.getPlatform(i).getName() for i in range(openmm.Platform.getNumPlatforms())]


def get_platform(name):
    """The OpenMM platform called ``name`` (error listing the installed ones)."""
    names = platform_names()
    if name not in names:
        raise ParameterError(f"OpenMM platform {name!r} is not installed here; available: {', '.join(names)}")
    return openmm.Platform.getPlatformByName(name)


@functools.lru_cache(maxsize=1)
def opencl_gpu_devices():
    """Names of the GPU devices offered by the OpenCL ICD loader (empty if none or no OpenCL).

    Queried with ``clGetPlatformIDs``/``clGetDeviceIDs(CL_DEVICE_TYPE_GPU)`` through ctypes,
    which costs milliseconds, unlike an OpenMM Context on OpenCL (kernel compilation).
    """
    path = ctypes.util.find_library("OpenCL")
    if path is None:
        return ()
    try:
        cl = ctypes.CDLL(path)
    except OSError:
        return ()
    n = ctypes.c_uint(0)
    if cl.clGetPlatformIDs(0, None, ctypes.byref(n)) != 0 or n.value == 0:
        return ()
    plats = (ctypes.c_void_p * n.value)()
    if cl.clGetPlatformIDs(n.value, plats, None) != 0:
        return ()
    names = []
    for p in plats:
        nd = ctypes.c_uint(0)
        if cl.clGetDeviceIDs(ctypes.c_void_p(p), ctypes.c_uint64(_CL_DEVICE_TYPE_GPU), 0, None,
                             ctypes.byref(nd)) != 0 or nd.value == 0:
            continue
        devs = (ctypes.c_void_p * nd.value)()
        cl.clGetDeviceIDs(ctypes.c_void_p(p), ctypes.c_uint64(_CL_DEVICE_TYPE_GPU), nd.value, devs, None)
        for d in devs:
            buf = ctypes.create_string_buffer(256)
            cl.clGetDeviceInfo(ctypes.c_void_p(d), ctypes.c_uint(0x102B), ctypes.c_size_t(256), buf, None)  # NAME
            names.append(buf.value.decode(errors="replace") or "GPU")
    return tuple(names)


def env_threads():
    """``OPENMM_CPU_THREADS`` (OpenMM's own variable; a Dask worker of dnarod sets 1) as an int, or None if unset.

    Raises
    ------
    ParameterError
        If it is set to anything but a whole number >= 1 (one line, not a traceback).
    """
    t = os.environ.get("OPENMM_CPU_THREADS", "").strip()
    if not t:
        return None
    if not t.isdigit() or int(t) < 1:
        raise ParameterError(f"OPENMM_CPU_THREADS={t!r}: give a whole number of threads >= 1 (or unset it)")
    return int(t)


def member_platform(platform=None, threads=None, elastic="auto"):
    """The platform a protocol member (tweezers, rings, nicked rings) runs on, resolved when its settings are made,
    so the settings (and the member's cache key) name it.

    Parameters
    ----------
    platform : str or None
        Platform asked for; ``None`` for the automatic choice of :func:`choose_platform` (with ``threads`` and
        ``elastic``): without a GPU and with one thread, the Reference platform. For a 1-kbp tweezers member in the
        exchange loop's pattern the CPU platform with one thread takes about twice the CPU time of Reference
        (docs/platforms.md).
    threads : int or None
        CPU platform threads; default :func:`env_threads` (a Dask worker sets 1), else 1.
    elastic : str
        The member's elastic path (``"portable"`` prefers the multithreaded CPU platform).

    Returns
    -------
    dict
        ``platform`` (str) and ``threads`` (int on the CPU platform, else None).
    """
    threads = int(threads or env_threads() or 1)
    name = platform or choose_platform(None, threads=threads, elastic=elastic)[0].getName()
    return dict(platform=name, threads=threads if name == "CPU" else None)


def platform_properties(name, threads=None, precision=None):
    """OpenMM platform properties for ``name``: ``Threads`` on CPU, ``Precision`` on GPU platforms."""
    props = {}
    if name == "CPU" and threads:
        props["Threads"] = str(int(threads))
    if name in GPU_PLATFORMS:
        props["Precision"] = precision or DEFAULT_GPU_PRECISION
    elif precision not in (None, "double"):
        raise ParameterError(f"precision {precision!r} applies to GPU platforms (CUDA, OpenCL, HIP) only; "
                             f"{name} computes in double precision")
    return props


def _gpu_elastic(name, elastic):
    """Which elastic path ``elastic`` gives on GPU platform ``name`` (for the reason line)."""
    if elastic in ("auto", "plugin"):
        if device_kernel(name)[0]:
            return "SMK force on the device (compiled plugin)"
    return "portable elastic path"


def choose_platform(requested=None, n_nodes=None, elastic="auto", threads=None, precision=None):
    """The OpenMM platform for a run, its properties and the reason for the choice.

    Parameters
    ----------
    requested : str or None
        Platform name (``--platform``); ``None`` or ``"auto"`` for the automatic choice.
    n_nodes : int or None
        Model size (chooses Reference or CPU for the CPU fast path).
    elastic : {"auto", "fast", "portable"}
        ``"fast"`` restricts the automatic choice to the CPU platforms.
    threads : int or None
        CPU platform threads. In the automatic choice, more than one thread asks for the CPU platform;
        ``None``, 0 or 1 give the single-threaded Reference platform (no worker-thread hand-off).
    precision : {"single", "mixed", "double"} or None
        GPU platforms' precision (default ``"mixed"``).

    Returns
    -------
    (openmm.Platform, dict, str)
        The platform, its properties and a one-line reason.
    """
    if requested not in (None, "auto"):
        plat = get_platform(requested)
        reason = f"{requested} (requested)"
        return plat, platform_properties(requested, threads, precision), reason
    names = platform_names()
    if elastic != "fast":
        for gpu in ("CUDA", "HIP"):
            if gpu in names:
                return (openmm.Platform.getPlatformByName(gpu), platform_properties(gpu, None, precision),
                        f"{gpu} (GPU found; {_gpu_elastic(gpu, elastic)})")
        if "OpenCL" in names:
            gpus = opencl_gpu_devices()
            if gpus:
                return (openmm.Platform.getPlatformByName("OpenCL"), platform_properties("OpenCL", None, precision),
                        f"OpenCL (GPU {gpus[0]}; {_gpu_elastic('OpenCL', elastic)})")
    if elastic == "portable":
        return (openmm.Platform.getPlatformByName("CPU"), platform_properties("CPU", threads, precision),
                "CPU (no GPU found; portable elastic path on the multithreaded CPU platform)")
    small = REFERENCE_MAX_NODES is None or (n_nodes is not None and n_nodes <= REFERENCE_MAX_NODES)
    multi = threads is not None and int(threads) > 1
    if small and not multi:
        return (openmm.Platform.getPlatformByName("Reference"), platform_properties("Reference", None, precision),
                "Reference (no GPU found; CPU fast path on the single-threaded Reference platform: no worker-thread "
                "hand-off per step)")
    why = f"{threads} threads requested" if multi else f"more than {REFERENCE_MAX_NODES} nodes"
    return (openmm.Platform.getPlatformByName("CPU"), platform_properties("CPU", threads, precision),
            f"CPU (no GPU found; CPU fast path, {why})")
