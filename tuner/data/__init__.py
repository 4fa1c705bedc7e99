"""Rig data in: raw files (``rigfile``), reading, units, checks and the dataset format (``reading``),
velocity and resampling to the fit rate (``preprocess``), what was understood (``summary``).
"""
