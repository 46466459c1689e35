"""Rod model validation, model files and the .dtraj trajectory stream."""
import numpy as np
import pytest

from dnarod.core.errors import DnarodError, GeometryError, ParameterError
from dnarod.core.forcefield import load_forcefield
from dnarod.core.model import RodModel
from dnarod.core.trajectory import Trajectory, TrajectoryWriter, load_trajectory


@pytest.fixture
def model():
    return load_forcefield("olson1998").model_from_sequence("CGCGAATTCGCG")


def test_model_save_load_round_trip(tmp_path, model):
    model.save(tmp_path / "m.npz")
    m2 = RodModel.load(tmp_path / "m.npz")
    assert np.array_equal(m2.positions, model.positions) and np.array_equal(m2.frames, model.frames)
    assert np.array_equal(m2.params.stiffness, model.params.stiffness)
    assert m2.sequence == model.sequence and m2.params.names == model.params.names and m2.ds == model.ds
    ring = load_forcefield("dna-default").model_from_sequence(n_nodes=21, circular=True)
    ring.save(tmp_path / "r.npz")
    r2 = RodModel.load(tmp_path / "r.npz")
    assert r2.circular and np.array_equal(r2.closure.Q, ring.closure.Q)
    assert abs(r2.energy()) < 1e-20


def test_model_rejects_bad_input(tmp_path, model):
    with pytest.raises(ParameterError, match="has 11 steps, but the parameters have 10"):
        RodModel(model.positions, model.frames, model.params[:10], model.ds, model.mass, model.inertia)
    with pytest.raises(ParameterError, match="base pair 4: mass must be positive"):
        m = model.mass.copy()
        m[3] = -1
        RodModel(model.positions, model.frames, model.params, model.ds, m, model.inertia)
    pos = model.positions.copy()
    pos[4, 1] = np.nan
    with pytest.raises(GeometryError, match="base pair 5: position is not finite"):
        model.with_pose(pos, model.frames)
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(ParameterError, match="junk.npz: cannot read dnarod model file"):
        RodModel.load(tmp_path / "junk.npz")


def test_trajectory_round_trip_is_bit_exact(tmp_path, model):
    rng = np.random.default_rng(0)
    n = model.n_nodes
    traj = Trajectory(np.arange(5) * 0.1, model.positions + rng.normal(0, 0.01, (5, n, 3)),
                      np.repeat(model.frames[None], 5, 0), np.arange(5) * 10,
                      rng.normal(size=(5, n, 3)), rng.normal(size=(5, n, 3)), {"dt": 0.01})
    traj.save(tmp_path / "t.dtraj")
    t2 = load_trajectory(tmp_path / "t.dtraj")
    for a in ("time", "positions", "frames", "step", "velocities", "angular_velocities"):
        assert np.array_equal(getattr(t2, a), getattr(traj, a)), a
    assert t2.metadata == {"dt": 0.01}


def test_partial_record_ignored_and_resume_truncates(tmp_path, model):
    path = tmp_path / "t.dtraj"
    n = model.n_nodes
    with TrajectoryWriter(path, n) as w:
        for s in range(0, 60, 10):
            w.write(s, s * 0.01, model.positions + s, model.frames)
    with open(path, "ab") as fh:  # a crash mid-write leaves a partial record
        fh.write(b"\x00" * 100)
    assert load_trajectory(path).n_frames == 6
    # resume from a checkpoint at step 30: frames 40 and 50 are dropped, then continued
    with TrajectoryWriter(path, n, resume_step=30) as w:
        for s in range(40, 80, 10):
            w.write(s, s * 0.01, model.positions + s, model.frames)
    t = load_trajectory(path)
    assert list(t.step) == list(range(0, 80, 10))
    assert np.allclose(t.positions[:, 0, 0] - model.positions[0, 0], t.step)
    with pytest.raises(DnarodError, match="cannot resume"):
        TrajectoryWriter(path, n + 1, resume_step=30)
    (tmp_path / "x.dtraj").write_bytes(b"garbage")
    with pytest.raises(DnarodError, match="not a dnarod .dtraj"):
        load_trajectory(tmp_path / "x.dtraj")


def test_ring_has_the_requested_linking_number_and_no_shear():
    from dnarod.physics.writhe import linking_number, twist, writhe

    ff = load_forcefield("dna-default")
    for n, dlk in ((105, 0), (105, -2), (60, 3)):
        ring = ff.ring(n_nodes=n, delta_linking_number=dlk)
        lk0 = round(n / 10.5)
        assert ring.circular and np.allclose(ring.closure.Q, np.eye(3)) and np.allclose(ring.closure.t, 0)
        Om, Ga = ring.strains()
        assert np.allclose(Ga[:, :2], 0, atol=1e-12) and np.allclose(Ga[:, 2], 1.0, rtol=1e-12)
        # independent geometry: Gauss linking number of the ribbon, writhe and twist of the polygon
        P = ring.positions
        lk = linking_number(P, P + 0.05 * ring.frames[:, :, 0])
        assert abs(lk - (lk0 + dlk)) < 1e-6
        assert abs(writhe(P)) < 1e-10
        assert abs(twist(P, ring.frames[:, :, 0]) - (lk0 + dlk)) < 1e-8
    relaxed, wound = ff.ring(n_nodes=105), ff.ring(n_nodes=105, delta_linking_number=2)
    assert wound.energy() > relaxed.energy() > 0  # bending a 105 bp ring costs energy; overwinding more
    with pytest.raises(ParameterError, match="integer"):
        ff.ring(n_nodes=50, linking_number=4.5)
