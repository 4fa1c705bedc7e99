"""The command line, one module per sub-command over the library (``tuner.job`` and the stages);
``tuner.__main__`` assembles the parser.

- ``fit``: ``fit`` and ``diagnose``;
- ``inspect``: ``inspect``, what the reader understands of rig files;
- ``batch``: ``batch``, a fleet from a manifest;
- ``vehicle``: ``vehicle``, damper FMUs in the campaign's vehicle;
- ``design``: ``design``, the rig tests that would pin down the parameters not determined;
- ``datasheet``: ``datasheet``, the damper's datasheet from its FMUs (and the rig's sine tests);
- ``options``: the shared options and their one mapping to settings;
- ``log``: the log and the progress display;
- ``folders``: output folders (``results/default-N``, ``--force``, ``--resume``);
- ``summary``: the end summary (printed and ``summary.json``);
- ``run``: exit handling (status 0, 1, 2, 130 and the hint to continue).
"""
