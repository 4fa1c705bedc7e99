"""The datasheet of several damper FMUs, as one record (``Datasheet``) and its files.

``make_datasheet`` runs every FMU's characteristics (``tuner.datasheet.characteristic``); ``write_datasheet`` writes

    datasheet.json                      the whole record (schema ``damper-datasheet/1``, docs/results.md), strict JSON
    <FMU>_force_velocity.csv            direction, velocity_m_s, force_n, series_stiffness_n_m: the table a
                                        multibody code's table dashpot with a series spring takes (signed, by velocity)
    <FMU>_maxwell.csv                   amplitude_m, frequency_hz, maxwell_k_n_m, maxwell_c_n_s_m, storage_n_m,
                                        loss_n_m, loss_angle_deg, distortion: per-frequency Maxwell parameters

and the figures beside them (``tuner.results.datasheet_figures``) into one folder (``<FMU>`` the FMU's file name
without ``.fmu``). SI units everywhere, stated in every key and column name; force positive in tension, velocity
positive in extension.
"""
from __future__ import annotations

import csv
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

from tuner import strict_json
from tuner.data.reading import RigTest
from tuner.datasheet.characteristic import DatasheetSettings, FmuCharacteristic, fmu_characteristic
from tuner.datasheet.measured import SineTest, model_point, point_errors, sine_test
from tuner.datasheet.nominal import NominalCharacteristic
from tuner.datasheet.sine_runs import SineDriver
from tuner.vehicle.cosim import check_damper_fmu

__all__ = ["SCHEMA", "DATASHEET_FILE", "DATASHEET_FOLDER", "Datasheet", "make_datasheet", "write_datasheet",
           "fmu_label", "format_datasheet_table", "compare_point"]

SCHEMA = "damper-datasheet/1"
DATASHEET_FILE = "datasheet.json"
#: the sub-folder of a fit output folder that holds its datasheet (the job's, ``python -m tuner datasheet --out RUN``)
DATASHEET_FOLDER = "datasheet"
UNITS = {"velocity": "m/s", "force": "N", "stroke and amplitude": "m", "frequency": "Hz", "stiffness": "N/m",
         "damping": "N s/m", "loss angle": "deg", "distortion": "1 (harmonics 2-20 over the first, rms)",
         "signs": "stroke and velocity positive in extension, force positive in tension"}


def fmu_label(fmu: Path) -> str:
    """The FMU's name in the datasheet and its files: its file name without ``.fmu``."""
    return Path(fmu).name.removesuffix(".fmu")


@dataclass
class Datasheet:
    """The datasheet: its ``settings``, the simulated ``characteristics`` by FMU label, the rig's ``sine_tests``
    (measured points) and the tests that are not (``not_sine``), the model's point at each measured one by FMU label
    (``comparisons``: dicts of ``compare_point``), the ``nominal`` characteristic every force-velocity point is
    judged against (None: none given), and ``seconds`` [s] wall."""

    settings: DatasheetSettings
    characteristics: dict = field(default_factory=dict)
    sine_tests: list = field(default_factory=list)
    not_sine: list = field(default_factory=list)
    comparisons: dict = field(default_factory=dict)
    nominal: NominalCharacteristic | None = None
    seconds: float = 0.0

    def nominal_record(self) -> dict | None:
        """The nominal characteristic and every force-velocity point judged against its band: ``judged`` by FMU
        label and ``measured`` (each point's ``source``), ``counts`` of inside / outside / not judged (beyond the
        nominal's velocities) for each; None without a nominal characteristic."""
        if self.nominal is None:
            return None
        judged = {label: [{**self.nominal.judge(p.velocity_m_s, p.force_n), "source": "simulated"}
                          for p in ch.force_velocity] for label, ch in self.characteristics.items()}
        judged["measured"] = [{**self.nominal.judge(sign * s.quantities.peak_velocity_m_s, force), "test": s.name,
                               "source": "measured"}
                              for s in self.sine_tests for sign, force in ((1.0, s.quantities.force_extension_n),
                                                                           (-1.0, s.quantities.force_compression_n))]
        counts = {k: {"inside": sum(p["inside"] is True for p in v), "outside": sum(p["inside"] is False for p in v),
                      "not_judged": sum(p["inside"] is None for p in v)} for k, v in judged.items()}
        return {**self.nominal.to_dict(), "judged": judged, "counts": counts}

    def to_dict(self) -> dict:
        """The record ``datasheet.json`` holds (docs/results.md, "The datasheet")."""
        fmus = {label: {**ch.to_dict(), "measured_comparison": self.comparisons.get(label, [])}
                for label, ch in self.characteristics.items()}
        return {"schema": SCHEMA, "units": UNITS, "settings": self.settings.to_dict(), "fmus": fmus,
                "measured": {"points": [s.to_dict() for s in self.sine_tests],
                             "not_sine": [n.to_dict() for n in self.not_sine]},
                "nominal": self.nominal_record(), "seconds": self.seconds}


def compare_point(driver: SineDriver, sine: SineTest) -> dict:
    """The model's point at the measured one ``sine`` (``tuner.datasheet.measured.model_point``) and its error."""
    model, settled = model_point(driver, sine)
    return {"test": sine.name, "frequency_hz": sine.quantities.frequency_hz, "amplitude_m": sine.quantities.amplitude_m,
            "model": {**model.to_dict(), "settled": settled, "source": "simulated"},
            "error": point_errors(model, sine.quantities)}


def make_datasheet(fmus: list, settings: DatasheetSettings = DatasheetSettings(), tests: list[RigTest] = (),
                   nominal: NominalCharacteristic | None = None, log=print) -> Datasheet:
    """The datasheet of the damper FMUs ``fmus`` (paths; FileNotFoundError naming a missing one, ValueError naming
    one that is not an FMI 2.0 co-simulation damper FMU, and for two of one name), with the measured points of the sine tests among the rig ``tests`` beside each FMU's
    (``tuner.datasheet.measured``) and every force-velocity point judged against the band of ``nominal``
    (``tuner.datasheet.nominal``). Each FMU is opened once (one fmpy instance, reset between its sines)."""
    settings.check()
    paths = [Path(f) for f in fmus]
    for p in paths:  # an FMI 2.0 co-simulation FMU with a damper's inputs and output, or an error naming it
        check_damper_fmu(p)
    labels = [fmu_label(p) for p in paths]
    if len(set(labels)) != len(labels):
        raise ValueError(f"datasheet: two FMUs of one name among {labels}: give FMUs of different file names")
    t0 = time.perf_counter()
    sheet = Datasheet(settings, nominal=nominal)
    for test in tests:
        read = sine_test(test)
        (sheet.sine_tests if isinstance(read, SineTest) else sheet.not_sine).append(read)
    if tests:
        log(f"datasheet: {len(sheet.sine_tests)} of {len(tests)} rig tests are sine tests (measured points)"
            + "".join(f"; {n.name}: {n.reason}" for n in sheet.not_sine[:3]))
    for path, label in zip(paths, labels):
        with SineDriver(path, settings.sine) as driver:
            sheet.characteristics[label] = fmu_characteristic(path, settings, driver=driver, log=log)
            sheet.comparisons[label] = [compare_point(driver, sine) for sine in sheet.sine_tests]
    sheet.seconds = time.perf_counter() - t0
    return sheet


def _write_csv(path: Path, header: list[str], rows: list[list]) -> Path:
    """A strict CSV (comma, header row, numbers as Python writes them; a non-finite number as an empty cell)."""
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for row in rows:
            w.writerow(["" if isinstance(v, float) and not math.isfinite(v) else
                        (repr(v) if isinstance(v, float) else v) for v in row])
    return path


def _tables(label: str, ch: FmuCharacteristic, out: Path) -> list[Path]:
    """``<label>_force_velocity.csv`` and ``<label>_maxwell.csv`` (module docstring)."""
    fv = _write_csv(out / f"{label}_force_velocity.csv",
                    ["direction", "velocity_m_s", "force_n", "series_stiffness_n_m"],
                    [[p.direction, p.velocity_m_s, p.force_n, ch.series_stiffness_n_m] for p in ch.force_velocity])
    mx = _write_csv(out / f"{label}_maxwell.csv",
                    ["amplitude_m", "frequency_hz", "maxwell_k_n_m", "maxwell_c_n_s_m", "storage_n_m", "loss_n_m",
                     "loss_angle_deg", "distortion"],
                    [[p.amplitude_m, p.frequency_hz, p.quantities.maxwell_k_n_m, p.quantities.maxwell_c_n_s_m,
                      p.quantities.storage_n_m, p.quantities.loss_n_m, p.quantities.loss_angle_deg,
                      p.quantities.distortion] for p in ch.dynamic])
    return [fv, mx]


def write_datasheet(sheet: Datasheet, out: Path) -> list[Path]:
    """The datasheet's files (module docstring; the figures are the report's, ``tuner.results.datasheet_figures``)
    into the folder ``out`` (created). Returns the paths written."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = [strict_json.write(out / DATASHEET_FILE, sheet.to_dict(), indent=1)]
    for label, ch in sheet.characteristics.items():
        paths += _tables(label, ch, out)
    return paths


def format_datasheet_table(sheet: dict) -> str:
    """The datasheet record ``sheet`` as text for the terminal: per FMU the force at each peak velocity [kN] in
    extension and compression, the series stiffness [MN/m], and the equivalent Maxwell k [MN/m] and c [kN s/m] at
    the smallest amplitude and each frequency."""
    lines = []
    for label, ch in sheet["fmus"].items():
        ext = {round(p["velocity_m_s"], 9): p["force_n"] for p in ch["force_velocity"] if p["direction"] == "extension"}
        comp = {round(-p["velocity_m_s"], 9): p["force_n"] for p in ch["force_velocity"]
                if p["direction"] == "compression"}
        lines += [f"{label}: series stiffness {ch['series_stiffness_n_m'] / 1e6:.4g} MN/m",
                  "  peak velocity [m/s]   force extension [kN]   force compression [kN]"]
        lines += [f"  {v:>19.4g}   {ext[v] / 1e3:>20.4g}   {comp.get(v, math.nan) / 1e3:>22.4g}" for v in sorted(ext)]
        a = min(p["amplitude_m"] for p in ch["dynamic"])
        lines.append(f"  at {a * 1e3:g} mm: frequency [Hz]   K' [MN/m]   K'' [MN/m]   loss angle [deg]   "
                     f"Maxwell k [MN/m]   c [kN s/m]   distortion [%]")
        lines += [f"  {p['frequency_hz']:>25.4g}   {p['storage_n_m'] / 1e6:>9.4g}   {p['loss_n_m'] / 1e6:>10.4g}   "
                  f"{p['loss_angle_deg']:>16.3g}   {_or_inf(p['maxwell_k_n_m'], 1e-6):>16}   "
                  f"{_or_inf(p['maxwell_c_n_s_m'], 1e-3):>10}   {100 * p['distortion']:>14.3g}"
                  for p in ch["dynamic"] if p["amplitude_m"] == a]
    return "\n".join(lines)


def _or_inf(value, scale: float) -> str:
    """``value`` x ``scale`` to 4 digits, or 'inf' (no equivalent element there, or a null read back)."""
    return "inf" if value is None or not math.isfinite(value) else f"{value * scale:.4g}"
