"""The filter a lab applied to its channels before exporting them, declared by the user (``--prefilter``).

Labs low-pass or smooth their channels (a moving average over a tenth of the sine period, a Butterworth
low-pass). The force of a nonlinear damper under a smoothed stroke is not the smoothed force, so a model
compared with filtered data meets a form error the lab made. Declared, the comparison is made as the
data were: the stroke that drives the model is the measured one with the filter undone (``unapply``:
divided by the filter's frequency response where it passes at least ``MIN_GAIN``, regularised below,
applied in ``tuner.identification.problem.to_signals``), and the simulated force passes the filter before
every comparison (identification, validation, diagnosis: the one place is
``tuner.identification.engine.Signals.band_limit``), on the model's own time grid. Filtering the
simulated force alone would count the filter's delay twice (the model under the filtered stroke already
lags); for a linear damper the two steps cancel exactly. When the lab filtered only the force (a
load-cell amplifier's low-pass), add ``:force-only``: the stroke is taken as measured.

Declaration (``--prefilter SPEC``, or the ``prefilter`` key of a ``--columns`` file, per file name):

* ``moving-average:T`` - mean over the last ``T`` seconds (causal, as a logger or a lab script
  computes it online: a delay of T / 2); ``moving-average:N@R`` - the mean of the last ``N`` samples of
  a channel sampled at ``R`` Hz (the lab's own samples: a delay of (N - 1) / (2 R));
  ``...:zero-phase`` - centred on each sample;
* ``butterworth:N:FC`` - Butterworth low-pass of order ``N`` and cut-off ``FC`` [Hz], causal;
  ``butterworth:N:FC:zero-phase`` - run forwards and backwards (``filtfilt``: squared magnitude,
  no delay);
* either followed by ``:force-only`` when the stroke was not filtered;
* ``none`` - no filter (the default).

A causal filter starts from rest at the first sample's value; the samples within its settling time
(``settling_s``: the moving average's window, ``N / FC`` for a Butterworth filter) do not count in any
comparison, at both ends when the filter is zero-phase or undone on the stroke.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy import signal

__all__ = ["Prefilter", "parse_prefilter"]

KINDS = ("moving-average", "butterworth")
#: ``unapply`` divides by the frequency response where its magnitude is at least this, and limits the gain
#: to 1 / MIN_GAIN below (what the filter removed there is not restored, nor its noise amplified further)
MIN_GAIN = 0.2


@dataclass(frozen=True)
class Prefilter:
    """A declared lab filter. kind: 'moving-average' (``window_s`` [s]) or 'butterworth' (``order``,
    ``cutoff_hz`` [Hz]); zero_phase: centred / forwards-backwards instead of causal; force_only: the stroke
    was not filtered."""

    kind: str
    window_s: float | None = None
    lab_rate_hz: float | None = None  # a moving average of window_s * lab_rate_hz samples at that rate
    order: int | None = None
    cutoff_hz: float | None = None
    zero_phase: bool = False
    force_only: bool = False

    @property
    def settling_s(self) -> float:
        """Time [s] after the start (and before the end, zero-phase) that a comparison leaves out."""
        return float(self.window_s) if self.kind == "moving-average" else float(self.order) / float(self.cutoff_hz)

    def describe(self) -> str:
        """One line for logs and reports, e.g. 'causal moving average over 20 ms'."""
        phase = "zero-phase" if self.zero_phase else "causal"
        which = " of the force only" if self.force_only else " of stroke and force"
        if self.kind == "moving-average":
            return f"{phase} moving average over {1e3 * self.window_s:.4g} ms{which}"
        return f"{phase} Butterworth low-pass, order {self.order}, cut-off {self.cutoff_hz:g} Hz{which}"

    @property
    def spec(self) -> str:
        """The declaration that gives this filter back (``parse_prefilter``)."""
        if self.kind == "butterworth":
            body = f"butterworth:{self.order}:{self.cutoff_hz!r}"
        elif self.lab_rate_hz:
            body = f"moving-average:{round(self.window_s * self.lab_rate_hz)}@{self.lab_rate_hz!r}"
        else:
            body = f"moving-average:{self.window_s!r}"
        return body + (":zero-phase" if self.zero_phase else "") + (":force-only" if self.force_only else "")

    def to_dict(self) -> dict:
        """What a test's metadata records: the fields, ``spec``, ``settling_s`` [s] and a text."""
        return {**asdict(self), "spec": self.spec, "settling_s": self.settling_s, "text": self.describe()}

    @property
    def delay_s(self) -> float:
        """A moving average's delay [s]: the centre of its window behind the sample it gives."""
        if self.zero_phase:
            return 0.0
        return 0.5 * self.window_s - (0.5 / self.lab_rate_hz if self.lab_rate_hz else 0.0)

    def apply(self, x: np.ndarray, rate_hz: float) -> np.ndarray:
        """``x`` sampled at ``rate_hz`` [Hz] passed through this filter (same length). A moving average is
        the mean over its window of ``x`` interpolated linearly between samples (exact for such a signal,
        on any grid: the window need not be a whole number of samples); before the first and after the
        last sample ``x`` is held."""
        x = np.asarray(x, dtype=float)
        if self.kind == "moving-average":
            t = np.arange(x.size) / rate_hz
            c = np.concatenate([[0.0], np.cumsum(0.5 * (x[1:] + x[:-1]) / rate_hz)])  # integral of x from 0

            def integral(u):
                inside = np.interp(u, t, c)
                return np.where(u < 0.0, x[0] * u, np.where(u > t[-1], c[-1] + x[-1] * (u - t[-1]), inside))

            centre, half = t - self.delay_s, 0.5 * self.window_s
            return (integral(centre + half) - integral(centre - half)) / self.window_s
        if self.cutoff_hz >= 0.5 * rate_hz:
            raise ValueError(f"prefilter: cut-off {self.cutoff_hz:g} Hz at or above the Nyquist frequency of "
                             f"the {rate_hz:g} Hz grid")
        sos = signal.butter(self.order, self.cutoff_hz, fs=rate_hz, output="sos")
        if self.zero_phase:
            return signal.sosfiltfilt(sos, x)
        return signal.sosfilt(sos, x, zi=signal.sosfilt_zi(sos) * x[0])[0]


    def response(self, freqs_hz: np.ndarray, rate_hz: float) -> np.ndarray:
        """Complex frequency response of ``apply`` at ``freqs_hz`` [Hz] on a grid of ``rate_hz`` [Hz]."""
        if self.kind == "moving-average":  # a window of window_s, its centre delay_s behind
            f = np.asarray(freqs_hz, dtype=float)
            return np.sinc(f * self.window_s) * np.exp(-2j * np.pi * f * self.delay_s)
        sos = signal.butter(self.order, self.cutoff_hz, fs=rate_hz, output="sos")
        h = signal.sosfreqz(sos, worN=np.asarray(freqs_hz, dtype=float), fs=rate_hz)[1]
        return np.abs(h) ** 2 if self.zero_phase else h

    def unapply(self, x: np.ndarray, rate_hz: float) -> np.ndarray:
        """``x`` (sampled at ``rate_hz`` [Hz]) with this filter undone: divided by its frequency response
        where it passes at least ``MIN_GAIN``, the gain limited to 1 / MIN_GAIN below. The signal is
        extended by its mirror image first (no jump at the ends); within ``settling_s`` of either end the
        result is approximate (those samples do not count)."""
        x = np.asarray(x, dtype=float)
        ext = np.concatenate([x, x[::-1]])
        freqs = np.fft.rfftfreq(ext.size, 1.0 / rate_hz)
        h = self.response(freqs, rate_hz)
        gain = np.conj(h) / np.maximum(np.abs(h) ** 2, MIN_GAIN ** 2)
        return np.fft.irfft(np.fft.rfft(ext) * gain, ext.size)[:x.size]


def parse_prefilter(spec: str | None, where: str = "--prefilter") -> Prefilter | None:
    """The ``Prefilter`` of a declaration (module docstring), None for ``none`` or None; ValueError naming
    ``where`` (the option or file key) and the accepted forms for anything else."""
    if spec is None or str(spec).strip().lower() in ("", "none"):
        return None
    forms = ("'moving-average:T' (T in s) or 'moving-average:N@R' (N samples at R Hz), 'butterworth:N:FC' "
             "(order, cut-off in Hz), each optionally "
             "followed by ':zero-phase' and ':force-only', or 'none'")
    parts = [p.strip().lower() for p in str(spec).split(":")]
    modifiers = set()
    while parts and parts[-1] in ("zero-phase", "force-only"):
        modifiers.add(parts.pop())
    zero_phase, force_only = "zero-phase" in modifiers, "force-only" in modifiers
    try:
        if parts[0] == "moving-average" and len(parts) == 2:
            if "@" in parts[1]:  # N samples at R Hz
                n, rate = int(parts[1].split("@")[0]), float(parts[1].split("@")[1].removesuffix("hz"))
                if not (n >= 1 and rate > 0):
                    raise ValueError
                window, lab_rate = n / rate, rate
            else:
                window, lab_rate = float(parts[1].removesuffix("s")), None
            if not window > 0:
                raise ValueError
            return Prefilter("moving-average", window_s=window, lab_rate_hz=lab_rate, zero_phase=zero_phase,
                             force_only=force_only)
        if parts[0] == "butterworth" and len(parts) == 3:
            order, cutoff = int(parts[1]), float(parts[2].removesuffix("hz"))
            if not (1 <= order <= 10 and cutoff > 0):
                raise ValueError
            return Prefilter("butterworth", order=order, cutoff_hz=cutoff, zero_phase=zero_phase,
                             force_only=force_only)
    except ValueError:
        pass
    raise ValueError(f"{where} {spec!r}: not a filter; give {forms}")
