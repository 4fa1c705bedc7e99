"""The command line, one module per sub-command over the library (``tuner.job`` and the stages):
``fit`` (fit and diagnose), ``inspect``, ``batch``, ``vehicle``; shared: the options and their mapping
to settings (``options``), the log and progress display (``log``), folders (``folders``), the end
summary (``summary``), exit handling (``run``). ``tuner.__main__`` assembles the parser.
"""
