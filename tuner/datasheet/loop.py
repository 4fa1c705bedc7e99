"""What a datasheet reads off one settled sine loop, the same way for a simulated and a measured one.

A stroke x(t) and force F(t) over a window of whole periods of the frequency f [Hz] are fitted by a Fourier
series in least squares (``harmonics``: the offset and harmonics 1..H; on a whole number of periods sampled
evenly this is the discrete Fourier transform). Complex amplitudes follow y(t) = Re(Y_n exp(i n w t)), so a
stroke A sin(w t) has X_1 = -i A. From the first harmonics (``LoopQuantities``):

    K* = F_1 / X_1 = K' + i K''        dynamic stiffness [N/m]: storage K', loss K'' (> 0 for a damper)
    |K*|, loss angle = atan2(K'', K')  [N/m], [deg]
    1 / K* = 1 / k + 1 / (i w c)       the equivalent Maxwell element (spring k in series with a dashpot c):
                                       k = |K*|^2 / K' [N/m], c = |K*|^2 / (w K'') [N s/m] (inf when K' <= 0)
    THD = sqrt(sum_{n=2..H} |F_n|^2) / |F_1|   the force's harmonic distortion [1] (0 for a linear damper)

and the force-velocity points: the force [N] at the instants of peak extension velocity (the stroke's
fundamental crossing zero upwards, velocity +w |X_1|) and of peak compression velocity (downwards, -w |X_1|),
interpolated linearly between samples and averaged over the window's periods. Signs: stroke and velocity
positive in extension, force positive in tension.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["HARMONICS", "Harmonics", "harmonics", "LoopQuantities", "loop_quantities", "maxwell_equivalent"]

#: harmonics fitted (and counted in the distortion), fewer where the sampling resolves fewer
HARMONICS = 20


@dataclass(frozen=True)
class Harmonics:
    """A Fourier series fitted to y(t): ``offset`` [unit of y] and ``amplitudes[n - 1]`` = Y_n (complex, n = 1..H),
    y(t) ~ offset + sum Re(Y_n exp(i n 2 pi f t)); ``frequency_hz`` [Hz]; ``residual_rms`` what the series
    leaves [unit of y]."""

    frequency_hz: float
    offset: float
    amplitudes: np.ndarray
    residual_rms: float

    @property
    def first(self) -> complex:
        """Y_1, the complex amplitude of the fundamental."""
        return complex(self.amplitudes[0])

    def distortion(self) -> float:
        """sqrt(sum_{n >= 2} |Y_n|^2) / |Y_1| [1] (nan when Y_1 is 0)."""
        y1 = abs(self.amplitudes[0])
        return float(np.sqrt(np.sum(np.abs(self.amplitudes[1:]) ** 2)) / y1) if y1 > 0 else math.nan


def _whole_periods(t: np.ndarray, frequency_hz: float) -> int:
    """The number of whole periods that ``t`` samples evenly (the samples of whole periods, the end excluded), 0
    when it does not."""
    dt = (t[-1] - t[0]) / (t.size - 1)
    periods = t.size * dt * frequency_hz
    m = round(periods)
    even = np.max(np.abs(np.diff(t) - dt)) <= 1e-9 * dt
    return m if (m >= 1 and even and abs(periods - m) <= 1e-9 * periods) else 0


def harmonics(t: np.ndarray, y: np.ndarray, frequency_hz: float, count: int = HARMONICS) -> Harmonics:
    """The Fourier series of ``y`` sampled at times ``t`` [s] at the fundamental ``frequency_hz`` [Hz], harmonics
    1..``count`` but none at or above the Nyquist frequency of the mean sample interval (nor more than the samples
    carry), fitted in least squares
    (module docstring): by the discrete Fourier transform where ``t`` samples whole periods evenly (the least-squares
    fit there, exactly), else by solving the normal equations. ValueError with fewer samples than unknowns."""
    t, y = np.asarray(t, dtype=float), np.asarray(y, dtype=float)
    dt = float((t[-1] - t[0]) / (t.size - 1))
    count = max(1, min(count, math.ceil(0.5 / (dt * frequency_hz)) - 1, (t.size - 2) // 2))
    if t.size < 2 * count + 2:
        raise ValueError(f"harmonics: {t.size} samples cannot carry {count} harmonics and an offset")
    n = np.arange(1, count + 1)
    shift = np.exp(-1j * n * 2 * np.pi * frequency_hz * t[0])  # referred to t = 0, not to the window's start
    m = _whole_periods(t, frequency_hz)
    if m:
        spec = np.fft.rfft(y) / t.size
        offset, amps = float(spec[0].real), 2 * spec[n * m] * shift
        rest = float(np.mean(y ** 2)) - offset ** 2 - 0.5 * float(np.sum(np.abs(amps) ** 2))
        return Harmonics(float(frequency_hz), offset, amps, math.sqrt(max(rest, 0.0)))
    phase = 2 * np.pi * frequency_hz * (t - t[0])
    basis = np.column_stack([np.ones_like(t), np.cos(np.outer(phase, n)), np.sin(np.outer(phase, n))])
    # einsum, not BLAS: OpenBLAS's threads made this product 1.2 s instead of 0.03 s on a busy 2-core machine
    coef = np.linalg.solve(np.einsum("ij,ik->jk", basis, basis), np.einsum("ij,i->j", basis, y))
    amps = (coef[1:count + 1] - 1j * coef[count + 1:]) * shift
    res = y - np.einsum("ij,j->i", basis, coef)
    return Harmonics(float(frequency_hz), float(coef[0]), amps, float(np.sqrt(np.mean(res ** 2))))


def maxwell_equivalent(k_star: complex, omega: float) -> tuple[float, float]:
    """(k [N/m], c [N s/m]) of the spring-dashpot series element with the dynamic stiffness ``k_star`` [N/m] at
    ``omega`` [rad/s]: k = |K*|^2 / K', c = |K*|^2 / (w K''); inf where K' or K'' is not positive (no such
    element: an inertia-dominated or active point)."""
    mag2 = abs(k_star) ** 2
    k = mag2 / k_star.real if k_star.real > 0 else math.inf
    c = mag2 / (omega * k_star.imag) if k_star.imag > 0 else math.inf
    return k, c


@dataclass(frozen=True)
class LoopQuantities:
    """The datasheet's quantities of one sine loop (module docstring), SI units: ``frequency_hz`` [Hz],
    ``amplitude_m`` |X_1| [m], ``peak_velocity_m_s`` w |X_1| [m/s], ``storage_n_m`` K', ``loss_n_m`` K'' [N/m],
    ``loss_angle_deg`` [deg], ``maxwell_k_n_m`` [N/m], ``maxwell_c_n_s_m`` [N s/m], ``distortion`` THD of the
    force [1], ``force_extension_n`` (> 0 for a damper) and ``force_compression_n`` (< 0) at the peak
    velocities [N], ``periods`` analysed, and ``stroke_distortion`` [1] (how far the stroke is from a sine)."""

    frequency_hz: float
    amplitude_m: float
    peak_velocity_m_s: float
    storage_n_m: float
    loss_n_m: float
    loss_angle_deg: float
    maxwell_k_n_m: float
    maxwell_c_n_s_m: float
    distortion: float
    force_extension_n: float
    force_compression_n: float
    periods: int
    stroke_distortion: float

    @property
    def dynamic_stiffness_n_m(self) -> float:
        """|K*| [N/m]."""
        return math.hypot(self.storage_n_m, self.loss_n_m)

    def to_dict(self) -> dict:
        """The quantities by name (the datasheet's keys), |K*| included."""
        d = {k: getattr(self, k) for k in self.__dataclass_fields__}
        return {**d, "dynamic_stiffness_n_m": self.dynamic_stiffness_n_m}


def _force_at_phase(t, force, frequency_hz: float, phase0: float, target: float) -> float:
    """The mean over the window's periods of ``force`` at the instants where the fundamental's phase
    w t + ``phase0`` equals ``target`` (mod 2 pi), linearly interpolated between samples [N]."""
    w = 2 * np.pi * frequency_hz
    first = math.ceil(((w * t[0] + phase0 - target) / (2 * np.pi)) - 1e-9)
    last = math.floor(((w * t[-1] + phase0 - target) / (2 * np.pi)) + 1e-9)
    instants = (target - phase0 + 2 * np.pi * np.arange(first, last + 1)) / w
    instants = instants[(instants >= t[0] - 1e-12) & (instants <= t[-1] + 1e-12)]
    return float(np.mean(np.interp(instants, t, force)))


def loop_quantities(t: np.ndarray, stroke: np.ndarray, force: np.ndarray, frequency_hz: float) -> LoopQuantities:
    """The quantities of the loop ``stroke`` [m], ``force`` [N] sampled at ``t`` [s], a window of whole periods of
    ``frequency_hz`` [Hz] (module docstring). The stroke's fundamental X_1 = |X_1| exp(i phi) puts the peak
    extension velocity where w t + phi = -pi/2 (mod 2 pi) and the peak compression velocity half a period on."""
    t = np.asarray(t, dtype=float)
    xh, fh = harmonics(t, stroke, frequency_hz), harmonics(t, force, frequency_hz)
    x1, f1 = xh.first, fh.first
    if abs(x1) == 0.0:
        raise ValueError("loop_quantities: the stroke has no fundamental at the frequency given")
    w = 2 * np.pi * frequency_hz
    k_star = f1 / x1
    k, c = maxwell_equivalent(k_star, w)
    phi = math.atan2(x1.imag, x1.real)
    # x = |X1| cos(w t + phi) -> v = -w |X1| sin(w t + phi): largest (extension) at w t + phi = -pi/2
    f_ext = _force_at_phase(t, force, frequency_hz, phi, -0.5 * np.pi)
    f_comp = _force_at_phase(t, force, frequency_hz, phi, 0.5 * np.pi)
    periods = int(round((t[-1] - t[0]) * frequency_hz))
    return LoopQuantities(frequency_hz=float(frequency_hz), amplitude_m=abs(x1), peak_velocity_m_s=w * abs(x1),
                          storage_n_m=k_star.real, loss_n_m=k_star.imag,
                          loss_angle_deg=math.degrees(math.atan2(k_star.imag, k_star.real)), maxwell_k_n_m=k,
                          maxwell_c_n_s_m=c, distortion=fh.distortion(), force_extension_n=f_ext,
                          force_compression_n=f_comp, periods=periods, stroke_distortion=xh.distortion())
