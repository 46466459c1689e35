"""False positives of the plectoneme detector on free coils: exact equilibrium samples of the open chain.

Usage: python free_coil.py [n_samples]

Each sample is :func:`dnarod.physics.thermal.equilibrium_sample` of a ``dna-default`` open chain (the force-free chain's
exact equilibrium; no excluded volume, so its self-approaches are an upper bound on those of the model with its
non-bonded terms). For each chain length and detector setting (minimum separation, contact distance): the mean
fraction of nodes in a self-contact and the share of samples flagged plectonemic (fraction >= 0.05). Settings: the
earlier fixed (25, 6) nm; the rule's distances for the calibrated charge at 0.15 M and for Manning's charge (5-Debye
cutoff); and the rule's contact distance without the raised minimum separation, at 0.05 M.
"""
import json
import sys

import numpy as np

from dnarod.core.forcefield import load_forcefield
from dnarod.physics.nonbonded import NonbondedSettings
from dnarod.workflows.protocols.measure import detector_distances, plectoneme_state
from dnarod.physics.thermal import equilibrium_sample

n_samp = int(sys.argv[1]) if len(sys.argv) > 1 else 200
ff = load_forcefield("dna-default")
cal = detector_distances(NonbondedSettings())
low = detector_distances(NonbondedSettings(salt=0.05))
settings = {"fixed 6 nm": (25.0, 6.0), "rule, calibrated 0.15 M": cal,
            "rule, Manning 5 Debye": detector_distances(NonbondedSettings(charge="manning", cutoff_debye=5.0)),
            "rule, calibrated 0.05 M": low, "0.05 M contact, 25-nm separation": (25.0, low[1])}
out = {}
for n_bp in (300, 400, 600, 1000, 2000):
    m = ff.model_from_sequence(n_nodes=n_bp)
    fr = np.zeros((n_samp, len(settings)))
    for k in range(n_samp):
        P = equilibrium_sample(m, 300.0, seed=1000 * n_bp + k).positions
        fr[k] = [plectoneme_state(P, m.ds, sep, con)[0] for sep, con in settings.values()]
    out[n_bp] = {name: dict(min_separation_nm=settings[name][0], contact_nm=settings[name][1],
                            fraction=float(fr[:, i].mean()), fraction_se=float(fr[:, i].std(ddof=1) / np.sqrt(n_samp)),
                            flagged=float((fr[:, i] >= 0.05).mean())) for i, name in enumerate(settings)}
    print(n_bp, "; ".join(f"{name}: {fr[:, i].mean():.4f} ({(fr[:, i] >= 0.05).mean():.3f})"
                          for i, name in enumerate(settings)), flush=True)
print(json.dumps(dict(n_samples=n_samp, temperature_K=300.0, results=out)))
