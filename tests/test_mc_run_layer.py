"""RunSpec(engine="mc") through the run layer: folder, energies CSV, observables, resume, CLI."""
import json

import numpy as np
import pytest

from dnarod.core.errors import ParameterError
from dnarod.physics.loads import Clamp, PullingForce, RotationClamp
from dnarod.run import RunSpec, run
from dnarod.core.units import PN


def _spec(**kw):
    loads = (Clamp(0), PullingForce(-1, [0.0, 0.0, 2.0 * PN]), RotationClamp(-1, 250.0))
    base = dict(source=40, engine="mc", time_ns=0.1, frame_interval_ps=10.0, loads=loads, seed=3, export=False)
    base.update(kw)
    return RunSpec(**base)


def test_mc_run_and_resume(tmp_path):
    res = run(_spec(), tmp_path / "r", progress=False)
    assert res.summary["steps"] == 100 and res.summary["engine"] == "mc"
    rows = (tmp_path / "r" / "energies.csv").read_text().splitlines()
    head = rows[0].split(",")
    assert "extension_nm" in head and "clamp_torque_pN_nm" in head
    assert len(rows) == 1 + 11
    meta = json.loads((tmp_path / "r" / "run.json").read_text())
    assert meta["dt_ps"] == 1.0
    # resume to 200 sweeps gives the same end state as one run of 200 sweeps
    run(_spec(time_ns=0.2), tmp_path / "r", resume=True, progress=False)
    run(_spec(time_ns=0.2), tmp_path / "s", progress=False)
    from dnarod.core.model import RodModel

    a = RodModel.load(tmp_path / "r" / "final_model.npz")
    b = RodModel.load(tmp_path / "s" / "final_model.npz")
    assert np.array_equal(a.positions, b.positions)


def test_mc_spec_refusals():
    with pytest.raises(ParameterError, match="temperature > 0"):
        _spec(temperature=0.0).check()
    with pytest.raises(ParameterError, match="no time step"):
        _spec(dt=0.01).check()
    with pytest.raises(ParameterError, match="platform"):
        _spec(platform="CUDA").check()
