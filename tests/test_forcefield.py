"""Parameter sets: schema checks, dna-default derivation, Olson conversion, exact persistence length."""

import numpy as np
import pytest

from dnarod.core.conversion import (jacobian_strains_to_step_parameters, step_parameters_to_strains,
                               stiffness_from_step_coordinates, stiffness_to_step_coordinates,
                               strains_to_step_parameters)
from dnarod.core.errors import ParameterError
from dnarod.core.forcefield import available_forcefields, load_forcefield, normalise_sequence
from dnarod.core.parameters import StepParameters
from dnarod.core.rotations import cayley
from dnarod.physics.thermal import mean_rotation, persistence_length
from dnarod.core.units import kT


def test_bundled_sets_load():
    assert {"dna-default", "olson1998", "uniform-rod"} <= set(available_forcefields())
    for name in available_forcefields():
        ff = load_forcefield(name)
        assert ff.ds > 0 and ff.node_mass > 0


def test_dna_default_file_equals_its_derivation():
    from dnarod.physics.dna_default import derive

    d = derive()
    K, xi0 = load_forcefield("dna-default").table["*"]
    Kd = np.block([[d["A"], d["B"]], [d["B"].T, d["C"]]])
    assert np.allclose(K, Kd, rtol=1e-10, atol=1e-9)
    assert np.allclose(xi0, np.concatenate([d["Omega0"], d["Gamma0"]]), rtol=1e-10)


def test_dna_default_physical_targets():
    ff = load_forcefield("dna-default")
    K, xi0 = ff.table["*"]
    kt = kT(300.0)
    theta0 = 2 * np.arctan(ff.ds * xi0[2] / 2)
    assert 2 * np.pi / theta0 == pytest.approx(10.5, rel=1e-10)
    assert ff.ds * xi0[5] == pytest.approx(0.34, rel=1e-12)
    # exact discrete persistence length (A5 iii)
    lp = persistence_length(StepParameters(K, xi0), ff.ds, kt)
    assert lp == pytest.approx(50.0, abs=1e-6)
    # it differs from the naive A1/kT: the Cayley correction is real (several percent)
    assert abs(K[0, 0] / kt - 50.0) > 4.0
    pN = 0.602214076  # kJ/mol/nm per pN
    assert (K[5, 5] - K[2, 5] ** 2 / K[2, 2]) / pN == pytest.approx(1100.0, rel=1e-10)
    assert K[2, 2] / np.cos(theta0 / 2) ** 4 / kt == pytest.approx(100.0, rel=1e-10)
    assert K[2, 5] / np.cos(theta0 / 2) ** 2 / pN == pytest.approx(-90.0, rel=1e-10)


def test_persistence_quadrature_against_monte_carlo():
    """Independent check of the exact transfer formula: importance-sampled <R33> under the Haar weight."""
    ff = load_forcefield("dna-default")
    K, xi0 = ff.table["*"]
    p = StepParameters(K, xi0)
    kt, ds = kT(300.0), ff.ds
    Rq = mean_rotation(p, ds, kt)[0]
    assert np.allclose(Rq, mean_rotation(p, ds, kt, order=40)[0], atol=1e-13)  # converged rule
    rng = np.random.default_rng(0)
    S = K[:3, :3] - K[:3, 3:] @ np.linalg.solve(K[3:, 3:], K[3:, :3])
    w = rng.multivariate_normal(ds * xi0[:3], kt * ds * np.linalg.inv(S), size=400_000)
    wt = (1 + 0.25 * np.einsum("qi,qi->q", w, w)) ** -2
    R33 = cayley(w)[:, 2, 2]
    mean = np.sum(wt * R33) / wt.sum()
    err = np.sqrt(np.sum(wt**2 * (R33 - mean) ** 2)) / wt.sum()
    assert abs(Rq[2, 2] - mean) < 4 * err
    assert err < 2e-5


def test_olson_round_trip_to_3dna_coordinates():
    """Intrinsic strains map back to the published mean step; K maps back to the published F."""
    import csv

    from dnarod.core.forcefield import data_dir

    ff = load_forcefield("olson1998")
    kt = kT(ff.temperature)
    table = data_dir() / "elastic/olson1998/olson1998_pdna_step_means_16.csv"
    rows = {r["step"]: r for r in csv.DictReader(open(table))}
    order = ["shift", "slide", "rise", "tilt", "roll", "twist"]
    F_pub = {}
    for r in csv.DictReader(open(data_dir() / "elastic/olson1998/olson1998_pdna_force_constants_16.csv")):
        F_pub.setdefault(r["step"], np.zeros((6, 6)))[order.index(r["row"])] = [float(r[c]) for c in order]
    assert len(ff.table) == 16
    for step, (K, xi0) in ff.table.items():
        p0 = np.array([float(rows[step][c]) for c in ("shift_A", "slide_A", "rise_A", "tilt_deg", "roll_deg",
                                                      "twist_deg")])
        p_back, F_back = stiffness_to_step_coordinates(xi0, K, ff.ds, kt)
        assert np.abs(p_back - p0).max() < 1e-10, step
        assert np.allclose(F_back, F_pub[step], rtol=1e-8, atol=1e-10), step


def test_jacobian_conversion_preserves_small_step_energies():
    """1/2 dp^T F dp (3DNA coordinates, kT) equals ds/2 dxi^T K dxi / kT to second order."""
    rng = np.random.default_rng(5)
    p0 = np.array([0.1, -0.4, 3.3, -1.0, 3.0, 34.0])
    X = rng.normal(size=(6, 6))
    F = X @ X.T / 10 + np.diag([1, 1, 5, 0.03, 0.03, 0.03])
    ds, kt = 0.34, 2.5
    xi0, K = stiffness_from_step_coordinates(p0, F, ds, kt)
    for eps in (1e-3, 5e-4):
        dxi = eps * rng.normal(size=6)
        dp = strains_to_step_parameters(xi0 + dxi, ds) - p0
        e_3dna = 0.5 * dp @ F @ dp
        e_cay = 0.5 * ds * dxi @ K @ dxi / kt
        assert abs(e_3dna - e_cay) < 20 * eps * e_cay  # agreement to O(eps) relative
    J = jacobian_strains_to_step_parameters(xi0, ds)
    # the Jacobian is invertible and the strains of the mean step are exact
    assert np.linalg.cond(J) < 1e4
    assert np.allclose(strains_to_step_parameters(step_parameters_to_strains(p0, ds), ds), p0, atol=1e-12)


def test_uniform_rod_from_material_constants():
    ff = load_forcefield("uniform-rod")
    K, _ = ff.table["*"]
    E = 0.3e9 * 6.02214076e-7  # Pa -> kJ/mol/nm^3
    G = 0.1e9 * 6.02214076e-7
    assert K[0, 0] == pytest.approx(E * np.pi / 4, rel=1e-12)
    assert K[2, 2] == pytest.approx(G * np.pi / 2, rel=1e-12)
    assert K[5, 5] == pytest.approx(E * np.pi, rel=1e-12)
    assert K[3, 3] == pytest.approx(0.9 * G * np.pi, rel=1e-12)
    # 1700 kg/m^3 = 1023.7 amu/nm^3; node = disc of radius 1 nm and thickness 0.34 nm
    assert ff.node_mass == pytest.approx(1700 / 1.66053906660 * np.pi * 0.34, rel=1e-10)
    assert ff.node_inertia[2] == pytest.approx(ff.node_inertia[0] + ff.node_inertia[1])


def test_sequence_mapping():
    ff = load_forcefield("olson1998")
    p = ff.step_parameters("acg T")
    assert p.names == ["AC", "CG", "GT"]
    assert np.allclose(p.stiffness[1], ff.table["CG"][0])
    assert ff.step_parameters("ACGT", circular=True).names[-1] == "TA"
    m = ff.model_from_sequence("ACGTTGCAAC")
    assert abs(m.energy()) < 1e-20
    ring = ff.model_from_sequence("ACGTTGCAAC", circular=True)
    assert ring.n_steps == 10 and abs(ring.energy()) < 1e-20


@pytest.mark.parametrize("seq, match", [("ACGU", "letter 'U' at position 4"), ("ACNT", "letter 'N' at position 3"),
                                        ("A", "at least 2"), (5, "string")])
def test_bad_sequences(seq, match):
    with pytest.raises(ParameterError, match=match):
        normalise_sequence(seq)


GOOD = """
name = "t"
kind = "uniform"
[step]
ds = { value = 0.34, unit = "nm" }
Omega0 = { value = [0, 0, 1.8], unit = "1/nm" }
Gamma0 = { value = [0, 0, 1], unit = "1" }
A = { value = [[100, 0, 0], [0, 100, 0], [0, 0, 200]], unit = "kJ/mol*nm" }
B = { value = [[0, 0, 0], [0, 0, 0], [0, 0, -50]], unit = "kJ/mol" }
C = { value = [[300, 0, 0], [0, 300, 0], [0, 0, 700]], unit = "kJ/mol/nm" }
[node]
mass = { value = 650, unit = "amu" }
inertia = { value = [117, 117, 234], unit = "amu*nm^2" }
"""


@pytest.mark.parametrize("old, new, match", [
    ("[0, 0, -50]], unit", "[0, 0, -50]], unit", None),
    ('A = { value = [[100, 0, 0]', 'A = { value = [[100, 5, 0]', r"not symmetric \(K\[0,1\]"),
    ("[0, 0, 700]]", "[0, 0, -700]]", "not positive definite"),
    (', unit = "kJ/mol/nm" }', ' }', "C: missing unit"),
    ('unit = "kJ/mol/nm" }', 'unit = "pN*nm" }', "C: unit 'pN\\*nm' is not a unit of energy/length"),
    ("[[300, 0, 0], [0, 300, 0], [0, 0, 700]]", "[[300, 0], [0, 300]]", r"C: expected shape \(3, 3\)"),
    ('kind = "uniform"', 'kind = "banana"', "kind must be"),
    ('mass = { value = 650, unit = "amu" }', '', "mass"),
])
def test_schema_errors_name_the_entry(tmp_path, old, new, match):
    f = tmp_path / "t.toml"
    f.write_text(GOOD.replace(old, new))
    if match is None:
        assert load_forcefield(f).name == "t"
    else:
        with pytest.raises(ParameterError, match=match):
            load_forcefield(f)


def test_unknown_step_type_and_name(tmp_path):
    with pytest.raises(ParameterError, match="unknown force field 'nope'"):
        load_forcefield("nope")
    ff = load_forcefield("olson1998")
    del ff.table["CG"]
    with pytest.raises(ParameterError, match=r"unknown step type\(s\) \['CG'\]"):
        ff.step_parameters("ACGT")
    f = tmp_path / "bad.toml"
    f.write_text("name = [")
    with pytest.raises(ParameterError, match="not valid TOML"):
        load_forcefield(f)


def test_sequence_cayley_write_and_load_round_trip(tmp_path):
    from dnarod.core.forcefield import write_forcefield

    ff = load_forcefield("olson1998")
    write_forcefield(tmp_path / "s.toml", "s", ff.table, ff.ds, 650.0, [117.0, 117.0, 234.0], sources=["test"])
    back = load_forcefield(tmp_path / "s.toml")
    assert back.kind == "sequence-cayley" and set(back.table) == set(ff.table)
    for k in ff.table:
        assert np.allclose(back.table[k][0], ff.table[k][0], rtol=1e-10)
        assert np.allclose(back.table[k][1], ff.table[k][1], rtol=1e-10, atol=1e-13)
    bad = (tmp_path / "s.toml").read_text().replace("[steps.AA]", "[steps.AX]")
    (tmp_path / "bad.toml").write_text(bad)
    with pytest.raises(ParameterError, match=r"\[steps.AX\] is not a dinucleotide"):
        load_forcefield(tmp_path / "bad.toml")
