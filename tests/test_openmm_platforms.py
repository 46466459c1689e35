"""Automatic choice of the OpenMM platform (dnarod.engines.openmm.platforms)."""
import pytest

from dnarod.core.errors import ParameterError
from dnarod.engines.openmm.platforms import (REFERENCE_MAX_NODES, choose_platform, opencl_gpu_devices, platform_names,
                                     platform_properties)


def _expected_gpu():
    names = platform_names()
    for gpu in ("CUDA", "HIP"):
        if gpu in names:
            return gpu
    if "OpenCL" in names and opencl_gpu_devices():
        return "OpenCL"
    return None


def test_requested_platform_is_used_and_unknown_is_an_error():
    plat, props, reason = choose_platform("Reference", 100)
    assert plat.getName() == "Reference" and props == {} and "requested" in reason
    plat, props, _ = choose_platform("CPU", 100, threads=1)
    assert plat.getName() == "CPU" and props == {"Threads": "1"}
    with pytest.raises(ParameterError, match="platform 'Nope' is not installed here; available: .*Reference"):
        choose_platform("Nope", 100)


def test_automatic_choice_never_picks_a_cpu_opencl():
    """With a GPU: the GPU platform (portable path). Without: the CPU fast path on the Reference
    platform (up to REFERENCE_MAX_NODES nodes, if set) -- never pocl's CPU OpenCL."""
    gpu = _expected_gpu()
    small, _, why_small = choose_platform(None, 1000)
    large, _, _ = choose_platform(None, 10**6)
    if gpu is not None:
        assert small.getName() == gpu and large.getName() == gpu and gpu in why_small
        return
    assert small.getName() == "Reference" and "no GPU" in why_small
    assert large.getName() == ("Reference" if REFERENCE_MAX_NODES is None or REFERENCE_MAX_NODES >= 10**6 else "CPU")
    assert choose_platform(None, 1000, threads=2)[0].getName() == "CPU"  # threads ask for the CPU platform
    # ... but one thread (a Dask worker's OPENMM_CPU_THREADS=1) is the Reference platform: no worker-thread hand-off
    assert choose_platform(None, 1000, threads=1)[0].getName() == "Reference"
    assert choose_platform(None, 1000, threads=0)[0].getName() == "Reference"
    assert choose_platform(None, 1000, elastic="portable")[0].getName() == "CPU"


def test_fast_path_request_stays_on_the_cpu():
    plat, _, _ = choose_platform(None, 1000, elastic="fast")
    assert plat.getName() in ("Reference", "CPU")


def test_precision_applies_to_gpu_platforms_only():
    assert platform_properties("OpenCL") == {"Precision": "mixed"}
    assert platform_properties("CUDA", precision="single") == {"Precision": "single"}
    with pytest.raises(ParameterError, match="precision 'single' applies to GPU platforms"):
        platform_properties("CPU", precision="single")


def test_opencl_device_query_is_cheap_and_safe():
    assert isinstance(opencl_gpu_devices(), tuple)


def test_simulation_records_the_choice():
    from dnarod.core.forcefield import load_forcefield
    from dnarod.engines.openmm.simulation import RodSimulation

    m = load_forcefield("dna-default").model_from_sequence("ACGTACGTAC")
    sim = RodSimulation.create(m, temperature=300, seed=1, nonbonded=False)
    assert sim.platform_name == (_expected_gpu() or "Reference")
    assert sim.platform_reason.startswith(sim.platform_name)
