"""From PDB-like input to base-pair nodes and back.

``reader`` (PDB/mmCIF -> nucleotides, through gemmi), ``frames`` (standard-base least-squares
frames), ``findpair`` (base pairs and helices by 3DNA's find_pair rules), ``pairing`` (what
dnarod adds: helix-context pairs, multiplets, explicit pairs, pair classes), ``bpparams``
(base-pair parameters and middle frames), ``conventions`` (3DNA's reversed frames for
left-handed DNA and B-Z junctions), ``analysis`` (the pipeline, also over trajectory frames),
``builders``
(RodModel from a structure or a sequence), ``rebuild`` (all-atom PDB from node frames),
the commands are in :mod:`dnarod.cli.structure` (``steps``, ``pairs``, ``build``, ``rebuild``).
"""
from dnarod.structure.analysis import analyze_structure, step_parameters_over_frames
from dnarod.structure.trajectory import read_duplex_trajectory
from dnarod.structure.builders import model_from_sequence, model_from_structure
from dnarod.structure.reader import read_structure
from dnarod.structure.rebuild import rebuild_coordinates, rebuild_model, write_pdb

__all__ = ["analyze_structure", "read_duplex_trajectory", "step_parameters_over_frames", "model_from_sequence",
           "model_from_structure", "read_structure", "rebuild_coordinates", "rebuild_model", "write_pdb"]
