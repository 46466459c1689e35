"""Shared fixtures: random heterogeneous chains, uniform rings of a given linking number."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dnarod.core.parameters import StepParameters
from dnarod.core.strains import chain_from_strains


def random_chain(seed, n=8, ds=0.34, twist=0.6, circular=False):
    """A random heterogeneous chain: intrinsic twist ``twist`` rad/step plus random bend and shear,
    its own random SPD 6x6 stiffness per step, and a pose with step rotations up to ~1.6 rad."""
    rng = np.random.default_rng(seed)
    m = n if circular else n - 1
    Omega = rng.normal(0.0, 0.6, (n - 1, 3))
    Omega[:, 2] += 2.0 / ds * np.tan(twist / 2)
    Gamma = rng.normal(0.0, 0.15, (n - 1, 3)) + [0.0, 0.0, 1.0]
    frame0 = Rotation.random(random_state=seed).as_matrix()
    pos, frm = chain_from_strains(Omega, Gamma, ds, r0=rng.normal(size=3), frame0=frame0)
    K = []
    for _ in range(m):
        X = rng.normal(size=(6, 6))
        K.append(100.0 * (X @ X.T + 2.0 * np.eye(6)))
    xi0 = rng.normal(0.0, 0.3, (m, 6))
    xi0[:, 2] += 2.0 / ds * np.tan(twist / 2)
    xi0[:, 5] += 1.0
    return pos, frm, StepParameters(np.array(K), xi0), ds


@pytest.fixture(params=[0, 1, 2, 3, 4])
def chain(request):
    return random_chain(request.param)


@pytest.fixture
def plot_labels(monkeypatch):
    """``draw(kind, rows, path) -> (legend labels, axes texts)``: a protocol curve drawn by
    :func:`dnarod.workflows.protocols.curves.plot_curve`, with what its legend and text calls received."""
    import matplotlib.axes

    from dnarod.workflows.protocols.curves import plot_curve

    labels, texts = [], []
    orig_legend, orig_text = matplotlib.axes.Axes.legend, matplotlib.axes.Axes.text

    def legend(self, *a, **k):
        labels.extend(self.get_legend_handles_labels()[1])
        return orig_legend(self, *a, **k)

    def text(self, x, y, s, *a, **k):
        texts.append(s)
        return orig_text(self, x, y, s, *a, **k)

    monkeypatch.setattr(matplotlib.axes.Axes, "legend", legend)
    monkeypatch.setattr(matplotlib.axes.Axes, "text", text)

    def draw(kind, rows, path):
        labels.clear()
        texts.clear()
        out = plot_curve(kind, rows, path)
        assert out.stat().st_size > 5000
        return list(labels), list(texts)

    return draw


def folder_snapshot(folder):
    """Every file under ``folder`` -> its bytes (to show that a refused command changed nothing)."""
    from pathlib import Path

    return {p: p.read_bytes() for p in sorted(Path(folder).rglob("*")) if p.is_file()}


@pytest.fixture
def assert_refused():
    """``check(work, args, words, strict=False)``: the CLI run with ``args`` (``{w}`` -> ``work``) exits 2 with one
    stderr line "dnarod: error: ..." holding every one of ``words``, prints nothing on stdout, changes no file
    under ``work`` (``strict``: adds none either) and leaves ``work/n`` empty or absent."""
    from click.testing import CliRunner

    from dnarod.cli.main import main

    def check(work, args, words, strict=False):
        before = folder_snapshot(work)
        r = CliRunner().invoke(main, [a.replace("{w}", str(work)) for a in args])
        assert r.exit_code == 2, (r.output, r.exception)
        assert r.stdout == ""
        err = r.stderr.strip()
        assert "\n" not in err and err.startswith("dnarod: error: "), err
        for w in words:
            assert w in err, (w, err)
        after = folder_snapshot(work)
        if strict:
            assert after == before
        for p, data in before.items():
            assert after.get(p) == data, f"{p} changed"
        assert not (work / "n").exists() or not any((work / "n").iterdir())

    def check_case(work, args, words, setup=None):
        """One misuse-table case: ``setup(work)`` (a context held during the call, e.g. a folder lock, or None),
        then :func:`check` with ``strict``."""
        held = setup(work) if setup is not None else None
        try:
            check(work, args, words, strict=True)
        finally:
            if held is not None:
                held.__exit__(None, None, None)

    check.case = check_case
    return check


def uniform_ring(n, linking_number, forcefield="dna-default"):
    """A closed ring of ``n`` uniform steps of ``forcefield`` with the integer ``linking_number`` (not relative to
    the relaxed twist, unlike ``ForceField.ring``)."""
    from dnarod.core.forcefield import load_forcefield
    from dnarod.core.model import RodModel

    base = load_forcefield(forcefield).model_from_sequence(n_nodes=n)
    p = base.params
    params = StepParameters(np.concatenate([p.stiffness, p.stiffness[:1]]),
                            np.concatenate([p.intrinsic, p.intrinsic[:1]]), list(p.names) + [p.names[0]])
    return RodModel.ring(params, base.ds, base.mass, base.inertia, linking_number=linking_number)
