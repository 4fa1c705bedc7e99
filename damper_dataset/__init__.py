"""Rig datasets (``damper-rig-dataset/1``). The virtual test campaign writes with it and the tuner
reads with it, so neither package depends on the other for data.

- ``format``: the format's definition, constants and checks (``check_signals``, ``read_manifest``, ``DataError``);
- ``writer``: the writer of a dataset folder (CSV files and ``manifest.json``).
"""
