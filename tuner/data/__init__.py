"""Rig data in: from a file as a rig or a logger wrote it to the tests prepared at the fit rate.

- ``rigfile``: the one place that picks a file's reader (by its content or its ending);
- ``raw_table``: a file's columns as written, whatever its format (``RawTable``), and the unit names it declares;
- ``delimited``: the delimited-text reader (delimiters, a logger's preamble, the header, a units row);
- ``mts793``: the MTS 793 data-acquisition export reader (its blocks, their stamps and checks);
- ``matlab_file``: the MATLAB ``.mat`` reader, version 5 and 7.3 (HDF5): variables, matrix columns, struct fields;
- ``parquet_file``: the Parquet reader;
- ``programme``: a test programme in one file: a stepped sine cut into its steps, and ``FILE@SEL`` picking some;
- ``units``: the units read and their exact factors to SI (metric and US customary);
- ``reading``: reading to SI units, signs, one test or several, and datasets (``load_tests``, ``load_dataset``);
- ``plausibility``: is it physically a damper on a rig (both directions), and the damper class's range;
- ``time_base``: stamps repaired to a regular clock, and a logger's declared sample rate checked;
- ``read_options``: the reader's options as one record (``ReadOptions``) and the column mapping file;
- ``stamps``: date-time stamps and their day-month order;
- ``calibration``: a logger's channel calibration (scale, offset) and the force tare;
- ``prefilter``: the lab's declared filter, applied to the simulated force and undone on the stroke;
- ``differentiator``: the stroke differentiator (Savitzky-Golay, designed for a band in Hz);
- ``preprocess``: velocity and anti-aliased resampling to the fit rate;
- ``noise``: the force noise [N] and whether it is credible;
- ``summary``: what was understood (``python -m tuner inspect``).
"""
