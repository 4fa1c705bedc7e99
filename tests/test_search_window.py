"""The global search's window of a test (tuner.identification.search_window): a periodic test is cut to the start
that covers its stroke and velocity range twice, a test that reaches its extremes late is left whole, and the
samples the low-pass cannot cover at the new end are not counted."""
import numpy as np

from tuner.identification.engine import Signals
from tuner.identification.search_window import search_window, search_windows


def _sine(cycles: float, f_hz: float = 0.5, rate_hz: float = 200.0, oversample: int = 1,
          warmup_s: float = 0.0) -> Signals:
    t = np.arange(0.0, cycles / f_hz, 1.0 / rate_hz)
    w = 2 * np.pi * f_hz
    x, v = 0.02 * np.sin(w * t), 0.02 * w * np.cos(w * t)
    return Signals("sine", t, x, v, 1e3 * v, t >= warmup_s, oversample=oversample)


def test_a_long_sine_is_cut_to_one_or_two_cycles():
    s = _sine(12, warmup_s=1.0)
    cut = search_window(s)
    period, counted_from = 2.0, 1.0
    length = cut.time[-1] - counted_from
    # the four extremes (stroke and velocity, within 5 % of their span) are all reached within a cycle of any
    # instant, so the second cover ends between one and two cycles after the counted start
    assert period <= length <= 2 * period, length
    assert np.array_equal(cut.force, s.force[:cut.time.size])  # the same samples, not resampled
    assert cut.mask.sum() >= 0.95 * (cut.time.size - 200)


def test_a_stroke_that_reaches_its_extremes_late_is_kept_whole():
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 20.0, 5e-3)
    x = np.cumsum(rng.normal(size=t.size)) * 1e-4
    x[-50] = x.max() + 1e-2  # an extreme near the end: the whole test is needed to see the range
    v = np.gradient(x, t)
    s = Signals("random", t, x, v, v, np.ones_like(t, dtype=bool))
    assert search_window(s) is s
    windows = search_windows([s, _sine(12)])
    assert windows.whole_s > windows.window_s > s.time[-1] - s.time[0]


def test_the_new_end_counts_only_samples_the_low_pass_covers():
    s = _sine(8, oversample=5)
    cut = search_window(s)
    assert cut.time.size < s.time.size
    k0, n = cut.band_limited_span()
    assert not cut.mask[k0 + n:].any() and not cut.mask[:k0].any()
    assert cut.mask[k0:k0 + n].all()
    assert s.mask.all()  # the whole test's mask is not touched


def test_a_search_on_windows_resumes_only_on_the_same_windows():
    whole = search_windows([_sine(1.0)])
    cut = search_windows([_sine(12)])
    assert whole.window_s == whole.whole_s and whole.keyed("abc") == "abc"  # as before the windows
    assert cut.keyed("abc") != "abc" and cut.keyed("abc") == search_windows([_sine(12)]).keyed("abc")
    assert cut.keyed("abc") != search_windows([_sine(10)]).keyed("abc")
