"""Rig data in: from a file as a rig or a logger wrote it to the tests prepared at the fit rate.

- ``rigfile``: raw files as written (delimiters, a logger's preamble, the header, units);
- ``reading``: reading to SI units, signs, plausibility and datasets (``load_tests``, ``load_dataset``);
- ``read_options``: the reader's options as one record (``ReadOptions``) and the column mapping file;
- ``stamps``: date-time stamps and their day-month order;
- ``calibration``: a logger's channel calibration (scale, offset) and the force tare;
- ``prefilter``: the lab's declared filter, applied to the simulated force and undone on the stroke;
- ``differentiator``: the stroke differentiator (Savitzky-Golay, designed for a band in Hz);
- ``preprocess``: velocity and anti-aliased resampling to the fit rate;
- ``noise``: the force noise [N] and whether it is credible;
- ``summary``: what was understood (``python -m tuner inspect``).
"""
