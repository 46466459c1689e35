"""From PDB-like input to base-pair nodes and back.

``reader`` (PDB/mmCIF -> nucleotides), ``frames`` (standard-base least-squares frames),
``pairing`` (base pairs and duplex ordering), ``bpparams`` (base-pair parameters and middle
frames), ``analysis`` (the whole pipeline), ``builders`` (RodModel from a structure or a
sequence), ``rebuild`` (all-atom PDB from node frames), ``cli_structure`` (CLI commands).
"""
