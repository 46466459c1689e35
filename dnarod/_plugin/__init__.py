"""The compiled OpenMM plugin (C++ sources in ``cpp/``; built by ``pip install``).

Do not import the extension from here directly: :mod:`dnarod.engines.openmm.plugin` loads it, checks it against
the installed OpenMM and falls back to the Python-callback path with one message if it is unusable.
"""
