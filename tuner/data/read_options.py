"""The reader's options as one record (``ReadOptions``), and the column mapping file that holds them.

Every option of ``tuner.data.reading.load_tests`` travels in a ``ReadOptions``: built by keyword
(``ReadOptions(stroke_unit="mm", force_col="Kraft")``), from a ``--columns`` mapping file
(:func:`read_column_mapping`'s options for every file, then one file's own, each applied with
:meth:`ReadOptions.merged`) and from the command line (``tuner.cli.options.column_options``, which
applies its options last: the command line wins). The defaults are the reader's: columns named
``time``, ``stroke`` and ``force``, units as the file declares them (else SI), our signs, the plausibility
checks on for a yaw damper.
"""
from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from pathlib import Path

from damper_dataset.format import DataError

__all__ = ["ReadOptions", "READ_OPTIONS", "COLUMN_OPTIONS", "DEFAULT_DAMPER_CLASS", "read_column_mapping"]

#: the damper class read by default (``tuner.data.plausibility.DAMPER_CLASSES``)
DEFAULT_DAMPER_CLASS = "yaw"


@dataclass(frozen=True, kw_only=True)
class ReadOptions:
    """How to read one rig file (``tuner.data.reading.load_tests``); every field optional, the defaults the
    reader's. Columns (``*_col``): a header, a header without its unit, or a 1-based position. Units
    (``*_unit``): None takes the unit the file declares (header ``force [kN]`` or a units row), else SI; a
    unit given and one declared must agree. Not hashable when a list or dict is given (``extra_cols``,
    ``channel_units``, ``metadata``). Build by keyword, :meth:`of` (with a clear error for an unknown
    option) or :meth:`merged` (overrides, e.g. a mapping file's per-file options)."""

    # -- columns
    time_col: str | int | None = "time"  # None (or no such column, with rate_hz): samples at rate_hz
    stroke_col: str | int = "stroke"
    force_col: str | int = "force"
    velocity_col: str | int | None = None  # the rig's measured stroke velocity (else the stroke is differentiated)
    temperature_col: str | int | None = None  # the oil temperature (None: a column named 'temperature' in degC/K)
    test_col: str | int | None = None  # test-id column: one test per value
    extra_cols: list | None = None  # channel columns to keep (None: every other column)
    header_line: int | None = None  # 1-based file line of the column names (None: detected after any preamble)
    # -- units: None = as the file declares, else SI
    time_unit: str | None = None  # 's' or 'ms' (numbers; date-time stamps are read as such)
    stroke_unit: str | None = None  # 'm', 'cm', 'mm', 'um'
    force_unit: str | None = None  # 'N', 'daN', 'kN'
    velocity_unit: str | None = None  # 'm/s', 'cm/s', 'mm/s', 'um/s' (None: the stroke unit per second)
    temperature_unit: str | None = None  # 'degC' or 'K'
    channel_units: dict | None = None  # other channel -> its unit (None: as each header declares)
    # -- signs: ours are extension and tension positive
    stroke_sign: int = 1  # -1: the rig writes compression as positive stroke
    force_sign: int = 1  # -1: the rig writes compression as positive force
    # -- time
    rate_hz: float | None = None  # [Hz] sample rate of a file without a time column (None: the preamble's)
    date_order: str | None = None  # 'mdy' or 'dmy' for year-last date stamps (None: from the data)
    t_start: float | None = None  # [s from the first sample] the segment used starts here
    t_end: float | None = None  # [s from the first sample] ... and ends here
    dt_tol: float = 0.01  # [-] relative tolerance of the time step (regular clock, declared rates)
    # -- calibration: engineering value = scale x raw + offset, in the channel's unit (tuner.data.calibration)
    stroke_scale: float | None = None  # [stroke unit per raw unit], > 0
    stroke_offset: float | None = None  # [stroke unit]
    force_scale: float | None = None  # [force unit per raw unit], > 0
    force_offset: float | None = None  # [force unit]
    velocity_scale: float | None = None  # [velocity unit per raw unit], > 0 (needs velocity_col)
    velocity_offset: float | None = None  # [velocity unit]
    force_zero: float | None = None  # [s] tare: the force's mean over the first seconds of each test removed
    prefilter: str | None = None  # the lab's filter on the channels, e.g. 'moving-average:0.02' (tuner.data.prefilter)
    # -- a test programme in one file (tuner.data.programme)
    programme: bool = False  # cut the file into the steps of a stepped sine, one test each
    steps: str | None = None  # the steps to read ('2', '1Hz', '1Hz:10mm', '1,3'; None: all); implies programme
    # -- checks
    check_plausible: bool = True  # refuse physically implausible strokes and forces (units)
    damper_class: str = DEFAULT_DAMPER_CLASS  # 'yaw', 'primary', 'secondary', 'any': the apparent damping's range
    # -- what the test is (set by load_files and load_dataset, not by a mapping file or the command line)
    name: str | None = None  # the test's name (None: the file name without extension)
    role: str | None = None  # 'identification' or 'validation' (damper_dataset.format.ROLES), or None
    scenario: str | None = None  # the dataset's scenario ('' when None)
    sample_rate_hz: float | None = None  # [Hz] the rate a dataset's manifest declares (checked against the time)
    metadata: dict | None = None  # free extra keys kept with the test

    def __new__(cls, /, **options):
        """Every ``ReadOptions(...)`` (and ``merged``) first: TypeError naming an unknown option and listing the
        known ones (a dataclass alone would not list them)."""
        unknown = [k for k in options if k not in READ_OPTIONS]
        if unknown:
            raise TypeError(f"unknown reader option(s) {unknown}; known: {', '.join(READ_OPTIONS)}")
        return super().__new__(cls)

    @classmethod
    def of(cls, options: ReadOptions | None = None, /, **changes) -> ReadOptions:
        """``options`` (None: the defaults) with single options given by keyword; TypeError naming an
        unknown option (and listing the known ones), or for ``options`` that is no ``ReadOptions``."""
        if options is not None and not isinstance(options, cls):
            raise TypeError(f"reader options must be a ReadOptions, got {type(options).__name__}; give single "
                            f"options by keyword")
        return (cls() if options is None else options).merged(changes)

    def merged(self, changes: Mapping | None = None, /, **more) -> ReadOptions:
        """A copy with the options of ``changes`` (a mapping, e.g. one file's entry of a mapping file) and
        ``more`` (keywords, applied last) replaced; TypeError naming an unknown option and listing the known."""
        given = {**(changes or {}), **more}
        return replace(self, **given) if given else self

    @property
    def columns(self) -> dict:
        """Role -> the column option: time, stroke, force, velocity, temperature, test."""
        return {"time": self.time_col, "stroke": self.stroke_col, "force": self.force_col,
                "velocity": self.velocity_col, "temperature": self.temperature_col, "test": self.test_col}

    @property
    def units(self) -> dict:
        """Channel -> the unit given (None: as declared): stroke, force, velocity, temperature."""
        return {"stroke": self.stroke_unit, "force": self.force_unit, "velocity": self.velocity_unit,
                "temperature": self.temperature_unit}

    @property
    def signs(self) -> dict:
        """{'stroke': +1 or -1, 'force': +1 or -1}."""
        return {"stroke": self.stroke_sign, "force": self.force_sign}

    @property
    def calibration(self) -> dict:
        """The calibration options by name (``tuner.data.calibration.calibration``'s input)."""
        return {k: getattr(self, k) for k in ("stroke_scale", "stroke_offset", "force_scale", "force_offset",
                                              "velocity_scale", "velocity_offset")}


#: every option of ``ReadOptions``, in its order
READ_OPTIONS = tuple(f.name for f in fields(ReadOptions))
#: the options a column mapping file (and the command line) may set: not the test's labels, the extra
#: columns, the channels' units or the time-step tolerance
COLUMN_OPTIONS = ("time_col", "stroke_col", "force_col", "velocity_col", "temperature_col", "test_col",
                  "time_unit", "stroke_unit", "force_unit", "velocity_unit", "temperature_unit", "stroke_sign",
                  "force_sign", "rate_hz", "t_start", "t_end", "check_plausible", "damper_class", "header_line",
                  "date_order", "stroke_scale", "stroke_offset", "force_scale", "force_offset", "velocity_scale",
                  "velocity_offset", "force_zero", "prefilter", "programme")


def read_column_mapping(path) -> tuple[dict, dict]:
    """Read a column mapping file (TOML or JSON) for campaigns of many files.

    Layout (TOML; JSON alike)::

        [columns]                # every file
        time_col = "Zeit"
        stroke_unit = "mm"
        [files."run_07.csv"]     # one file (by name), over [columns]
        force_sign = -1

    Keys: the options of ``ReadOptions`` listed in ``COLUMN_OPTIONS``. Returns (every file, file name ->
    options), plain dicts: ``ReadOptions().merged(every).merged(per_file.get(name, {}))`` is one file's
    record. Raises DataError naming the file and the unknown key.
    """
    import tomllib

    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise DataError(f"{path}: cannot read the column mapping: {exc}") from exc
    try:
        data = json.loads(text) if path.suffix.lower() == ".json" else tomllib.loads(text)
    except (json.JSONDecodeError, tomllib.TOMLDecodeError) as exc:
        raise DataError(f"{path}: invalid {'JSON' if path.suffix.lower() == '.json' else 'TOML'}: {exc}") from exc
    extra = [k for k in data if k not in ("columns", "files")]
    if extra:
        raise DataError(f"{path}: unknown section(s) {extra}; expected 'columns' and 'files'")

    def check(opts, where):
        if not isinstance(opts, dict):
            raise DataError(f"{path}: {where} must be a table of options")
        bad = [k for k in opts if k not in COLUMN_OPTIONS]
        if bad:
            raise DataError(f"{path}: {where}: unknown option(s) {bad}; known: {', '.join(COLUMN_OPTIONS)}")
        return dict(opts)

    common = check(data.get("columns", {}), "[columns]")
    files = data.get("files", {})
    if not isinstance(files, dict):
        raise DataError(f"{path}: [files] must map file names to options")
    return common, {name: check(o, f"[files.{name!r}]") for name, o in files.items()}
