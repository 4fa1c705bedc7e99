"""Rig datasets (``damper-rig-dataset/1``): the format and its checks (``format``), the writer
(``writer``). The virtual test campaign writes with it and the tuner reads with it, so neither
package depends on the other for data."""
