"""Random processes and the IEEE Std 952 noise terms: white noise, bias instability (flicker or
Gauss–Markov), random walk, Gauss–Markov, quantization noise and rate ramp, each with what a
stochastic-model fit needs (Haar wavelet variance, discrete PSD; Percival & Walden 2000).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, ClassVar

import numpy as np

from ..errors import GyrosimError
from ..lazy import lazy_module
from ..units import DEG, G0
from .base import ANY_TRIAD, Effect, _need_rng, _vec

# heavy libraries the functions below call, imported on first use (gyrosim.lazy): not at start-up
sp_fft = lazy_module("scipy.fft")
sp_signal = lazy_module("scipy.signal")
kern = lazy_module("gyrosim._kernels")

__all__ = ["WhiteNoise", "BiasInstability", "RandomWalk", "GaussMarkov", "QuantizationNoise", "RateRamp",
           "spectral_noise", "haar_gain2"]


def spectral_noise(effects: list["Effect"], n: int, fs: float, rng: np.random.Generator) -> np.ndarray:
    """One (N, 3) realisation of the summed stationary Gaussian processes of ``effects``.

    Spectrum drawn directly in the frequency domain: for the two-sided PSD S(f), the rFFT bin k
    of a length-n real sequence has E|X_k|² = n f_s S(f_k) (n f_s S for k = 0 and Nyquist,
    which are real), so X_k = √(n f_s S(f_k)/2) (g₁ + i g₂) for 0 < k < n/2; irfft then gives
    E[x²] = Σ S Δf over [−f_s/2, f_s/2], the discrete white sequence of σ² = N² f_s for S = N².
    The DC bin is zero (a constant belongs to the bias effect).
    """
    f = np.fft.rfftfreq(n, 1.0 / fs)
    psd = sum(e.psd_two_sided(f) for e in effects)  # (3, F)
    amp = np.sqrt(psd * (n * fs / 2.0))
    g = rng.standard_normal((3, f.size, 2)).view(complex)[..., 0]  # g₁ + i g₂ without temporaries
    spec = g
    spec *= amp
    spec[:, 0] = 0.0
    if n % 2 == 0:  # Nyquist bin of a real signal is real: E|X|² = n f_s S with one real normal
        spec[:, -1] = np.sqrt(2.0) * spec[:, -1].real
    return sp_fft.irfft(spec, n=n, axis=1, workers=-1).T


def haar_gain2(f_cyc: np.ndarray, m: int) -> np.ndarray:
    """|H_m(f)|² of the level-j Haar MODWT filter (half-length m = 2^{j−1}; taps ±1/(2m)):
    sin⁴(π f m) / (m² sin²(π f)), f in cycles/sample (Percival & Walden 2000 eq. 163)."""
    s = np.sin(np.pi * f_cyc)
    return np.sin(np.pi * f_cyc * m) ** 4 / (m * m * s * s)


@lru_cache(maxsize=4096)
def _haar_integral_flicker(m: int) -> float:
    """2 ∫_0^½ |H_m(f)|² / (2π f) df: the Haar wavelet variance of a unit flicker process (S(f) =
    1/(2π|f|) per sample).  Core f < 32/m on a fine grid in u = f m (128 points per period of
    sin⁴), beyond it sin⁴(π f m) is replaced by its mean 3/8 (the rest of the integrand is smooth)."""
    f1 = min(0.5, 32.0 / m)
    u = np.linspace(1e-9, f1 * m, 8193)
    f = u / m
    core = float(np.trapezoid(haar_gain2(f, m) / (2 * np.pi * f), f))
    tail = 0.0
    if f1 < 0.5:
        ft = np.geomspace(f1, 0.5, 2049)
        tail = float(np.trapezoid(0.375 / (m * m * np.sin(np.pi * ft) ** 2) / (2 * np.pi * ft), ft))
    return 2.0 * (core + tail)


def _ar1_draw(n: int, dt_s: float, sigma: np.ndarray, tau_s: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """(n, 3) first-order Gauss–Markov process, exact discretisation: b_{k+1} = φ b_k + σ √(1 − φ²) w_k,
    φ = e^{−Δt/τ}, started from its stationary N(0, σ²) (Maybeck 1979 §4.11)."""
    phi = np.exp(-dt_s / np.asarray(tau_s, float))
    w = rng.standard_normal((n, 3)) * (sigma * np.sqrt(1 - phi**2))
    w[0] = rng.standard_normal(3) * sigma
    out = np.empty_like(w)
    for i in range(3):
        out[:, i] = sp_signal.lfilter([1.0], [1.0, -phi[i]], w[:, i])
    return out


def _ar1_haar(m: np.ndarray, dt_s: float, sigma: np.ndarray, tau_s: np.ndarray) -> np.ndarray:
    """Haar wavelet variance (3, J) of the sampled Gauss–Markov process (σ², φ = e^{−Δt/τ}):
    ν² = [Var S_m − Cov(S_m, S'_m)] / (2 m²) with the sums of m consecutive samples
    Var S_m = σ² [m (1+φ)/(1−φ) − 2φ(1−φ^m)/(1−φ)²], Cov = σ² φ (1−φ^m)²/(1−φ)² (geometric sums of
    the autocovariance σ² φ^|k|; Guerrier et al. 2013 give the same closed form)."""
    m = np.asarray(m, float)[None, :]
    a = (dt_s / np.asarray(tau_s, float))[:, None]
    phi = np.exp(-a)
    one_m = -np.expm1(-a)               # 1 − φ without cancellation
    one_mm = -np.expm1(-a * m)          # 1 − φ^m
    var_s = m * (1 + phi) / one_m - 2 * phi * one_mm / one_m**2
    cov = phi * one_mm**2 / one_m**2
    return (np.asarray(sigma, float) ** 2)[:, None] * (var_s - cov) / (2 * m * m)


@dataclass(frozen=True)
class WhiteNoise(Effect):
    """White measurement noise: ARW (gyro) or VRW (accelerometer).

    ``density`` is the IEEE-952 coefficient N (rad/s/√Hz = rad/√s, or m/s²/√Hz): the Allan
    deviation is N/√τ and each sample gets σ = N √f_s (see :mod:`gyrosim.units`).
    """

    kind: ClassVar[str] = "white_noise"
    closeloop_reason: ClassVar[str] = (
        "the noise floor itself: its level is the held-out residual the loop reports, not a term to fit")
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate_density", "accelerometer": "acceleration_density",
                                            "magnetometer": "magnetic_field_density"}
    stochastic: ClassVar[bool] = True
    invertible: ClassVar[bool] = False
    is_white_noise: ClassVar[bool] = True
    param_fields: ClassVar[tuple[str, ...]] = ("density",)
    density: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @classmethod
    def preset_to_si(cls, raw: dict[str, Any], unit: str, quantity: str) -> dict[str, Any]:
        """Datasheets quote N two ways: ``convention = "ieee952"`` (default; the two-sided PSD N²,
        σ_A = N/√τ) or ``"one-sided"`` (the one-sided PSD 2N², so N = value/√2)."""
        raw = dict(raw)
        convention = raw.pop("convention", "ieee952")
        if convention not in ("ieee952", "one-sided"):
            raise GyrosimError("white_noise convention must be 'ieee952' or 'one-sided'")
        raw = super().preset_to_si(raw, unit, quantity)
        if convention == "one-sided":
            raw["density"] = np.asarray(raw["density"]) / np.sqrt(2.0)
        return raw

    def __post_init__(self) -> None:
        d = _vec(self.density, name="noise density")
        if np.any(d < 0):
            raise GyrosimError(f"noise density must be >= 0, got {d.tolist()}")
        object.__setattr__(self, "density", d)

    def delta(self, x, ctx, rng=None):
        rng = _need_rng(rng, self.kind)
        return rng.standard_normal(x.shape) * (self.density * math.sqrt(ctx.rate_hz))

    def add_delta(self, y, x, ctx, rng=None):
        kern.add_scaled(y, _need_rng(rng, self.kind).standard_normal(x.shape), self.density * math.sqrt(ctx.rate_hz))

    def ieee952_terms(self):
        return {"arw": self.density}

    def sample_noise_variance(self, rate_hz):
        # σ = N √f_s per sample
        return self.density**2 * rate_hz

    noise_parameters: ClassVar[tuple[str, ...]] = ("density",)
    noise_short_name: ClassVar[str] = "white"
    noise_rank: ClassVar[int] = 0
    noise_si_units: ClassVar[dict[str, str]] = {"gyro": "rad/s/sqrt(Hz)", "accelerometer": "m/s^2/sqrt(Hz)"}
    noise_datasheet_units: ClassVar[dict[str, str]] = {
        "gyro": "deg/sqrt(h)",
        "accelerometer": "ug/sqrt(Hz) (two-sided)",
    }

    @classmethod
    def noise_units(cls, field, value, rate_hz, triad):
        # two-sided PSD N² (Kalibr noise_density), one-sided 2N², per sample σ = N √f_s; 1 °/s/√Hz = 60 °/√h
        out = {"continuous_two_sided (Kalibr noise_density)": value, "one_sided": math.sqrt(2) * value,
               "discrete_sigma_per_sample": value * math.sqrt(rate_hz)}
        out.update(
            {"deg/sqrt(h)": value / DEG * 60.0}
            if triad == "gyro"
            else {
                "ug/sqrt(Hz) (two-sided)": value / G0 * 1e6,
                "ug/sqrt(Hz) (one-sided)": math.sqrt(2) * value / G0 * 1e6,
            }
        )
        return out

    def haar_wavelet_variance(self, m, dt_s):
        # σ² = N²/Δt per sample; ν² = σ²/(2m) (P&W 2000 eq. 296)
        return (self.density**2 / dt_s)[:, None] / (2 * np.asarray(m, float))[None, :]

    def discrete_psd(self, f_cyc, dt_s):
        return np.repeat((self.density**2 / dt_s)[:, None], np.size(f_cyc), axis=1)


@dataclass(frozen=True)
class BiasInstability(Effect):
    """Bias instability: a first-order Gauss–Markov process (``model = "gauss_markov"``) or
    flicker (1/f) noise (``model = "flicker"``), sized by the datasheet bias instability B.

    * Gauss–Markov, exact discretisation: b_{k+1} = φ b_k + σ √(1 − φ²) w_k, φ = e^{−Δt/τ},
      stationary σ = B / 0.664 so that the Allan-deviation bump (≈ 0.62 σ at τ ≈ 1.9 τ_c) sits
      near B's floor; starts from its stationary distribution.
    * Flicker: white noise shaped to the two-sided PSD S(f) = B² / (2π f) (IEEE Std 952 Annex C
      convention, as the ARW N²) for 1/T ≤ f ≤ f_s/2; its Allan deviation is flat at
      √(2 ln 2/π) B = 0.664 B for 1/f_s ≪ τ ≪ T.
    """

    kind: ClassVar[str] = "bias_instability"
    closeloop_reason: ClassVar[str] = (
        "tested together with random_walk as 'bias drift' (one slow bias; one recording cannot "
        "separate the two spectra reliably)")
    quantities: ClassVar[dict[str, str]] = ANY_TRIAD
    stochastic: ClassVar[bool] = True
    invertible: ClassVar[bool] = False
    param_fields: ClassVar[tuple[str, ...]] = ("value",)
    value: np.ndarray = field(default_factory=lambda: np.zeros(3))
    tau_s: float = 100.0
    model: str = "flicker"

    def __post_init__(self) -> None:
        v = _vec(self.value, name="bias instability")
        if np.any(v < 0):
            raise GyrosimError("bias instability must be >= 0")
        object.__setattr__(self, "value", v)
        if self.model not in ("flicker", "gauss_markov"):
            raise GyrosimError(f"bias_instability model {self.model!r}: use 'flicker' or 'gauss_markov'")
        if not (math.isfinite(self.tau_s) and self.tau_s > 0):
            raise GyrosimError("bias_instability tau_s must be > 0 s")

    def delta(self, x, ctx, rng=None):
        return self.delta_on_grid(x.shape[0], ctx.dt_s, _need_rng(rng, self.kind))

    def delta_on_grid(self, n, dt_s, rng):
        if self.model == "gauss_markov":  # the gauss_markov effect's process, sized by B
            return _ar1_draw(n, dt_s, self.value / 0.664, np.full(3, self.tau_s), rng)
        return spectral_noise([self], n, 1.0 / dt_s, rng)

    def coarse_step_s(self, white_density, dt_s):
        # flicker: B²/(2π f) ≤ 0.01 N²  ⇔  f ≥ 100 B²/(2π N²);  Gauss–Markov (σ², τ): its PSD
        # 2σ²τ/(1 + (2πfτ)²) ≤ 2σ²/(τ(2πf)²) ≤ 0.01 N²  ⇔  f ≥ √(200 σ²/τ)/(2π N)
        if np.any(white_density <= 0):
            return None
        if self.model == "flicker":
            f_min = float(np.max(100 * self.value**2 / (2 * math.pi * white_density**2)))
        else:
            sigma = self.value / 0.664
            f_min = float(np.max(np.sqrt(200 * sigma**2 / self.tau_s) / (2 * math.pi * white_density)))
        return 1.0 / (2.0 * f_min) if f_min > 0 else None

    def psd_two_sided(self, f_hz):
        if self.model != "flicker":
            return None
        out = np.zeros((3, f_hz.size))
        pos = f_hz > 0
        out[:, pos] = (self.value**2)[:, None] / (2 * math.pi * f_hz[pos])
        return out

    def noise_model_term(self):
        # the gauss_markov effect's process, sized by B (σ = B/0.664)
        if self.model == "gauss_markov":
            return GaussMarkov(sigma=self.value / 0.664, tau_s=np.full(3, self.tau_s))
        return self

    def ieee952_terms(self):
        # a Gauss–Markov process is not one of the three terms (its Allan curve has a bump)
        return {"bias_instability": self.value} if self.model == "flicker" else {}

    # a noise fit builds this effect with its default model, flicker (a Gauss–Markov term is the
    # gauss_markov effect, sized by σ and τ rather than by B)
    noise_parameters: ClassVar[tuple[str, ...]] = ("value",)
    noise_short_name: ClassVar[str] = "flicker"
    noise_rank: ClassVar[int] = 2
    noise_si_units: ClassVar[dict[str, str]] = {"gyro": "rad/s", "accelerometer": "m/s^2"}
    noise_datasheet_units: ClassVar[dict[str, str]] = {"gyro": "deg/h", "accelerometer": "ug"}

    @classmethod
    def noise_units(cls, field, value, rate_hz, triad):
        # the Allan floor of flicker noise is 0.664 B (IEEE Std 952)
        out = {"B": value, "allan_floor_0.664B": 0.664 * value}
        out.update({"deg/h": value / DEG * 3600} if triad == "gyro" else {"ug": value / G0 * 1e6})
        return out

    def haar_wavelet_variance(self, m, dt_s):
        if self.model == "gauss_markov":
            return _ar1_haar(m, dt_s, self.value / 0.664, np.full(3, self.tau_s))
        coef = np.array([_haar_integral_flicker(int(mi)) for mi in np.asarray(m).ravel()])
        return (self.value**2)[:, None] * coef[None, :]

    def discrete_psd(self, f_cyc, dt_s):
        f = np.abs(np.asarray(f_cyc, float))
        if self.model == "gauss_markov":
            return GaussMarkov(sigma=self.value / 0.664, tau_s=np.full(3, self.tau_s)).discrete_psd(f, dt_s)
        # S_c(F) = B²/(2πF) (Hz) sampled at f_s: S_d(f) = f_s S_c(f f_s) = B²/(2π f)
        return (self.value**2)[:, None] / (2 * np.pi * np.maximum(f, 1e-300))[None, :]


@dataclass(frozen=True)
class RandomWalk(Effect):
    """Rate random walk (gyro) / acceleration random walk: the Wiener process
    b_k = Σ K √Δt w_j starting at 0 at power-on, so σ_A(τ) = K √(τ/3); K in rad/s/√s or m/s²/√s.
    (Not synthesised spectrally: a periodic 1/f² spectrum lacks the power below 1/T and biased
    K low by 3.5 % over 2 h in our Monte Carlo.)"""

    kind: ClassVar[str] = "random_walk"
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate_random_walk", "accelerometer": "acceleration_random_walk",
                                            "magnetometer": "magnetic_field_random_walk"}
    stochastic: ClassVar[bool] = True
    invertible: ClassVar[bool] = False
    param_fields: ClassVar[tuple[str, ...]] = ("value",)
    value: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        v = _vec(self.value, name="random walk")
        if np.any(v < 0):
            raise GyrosimError("random walk must be >= 0")
        object.__setattr__(self, "value", v)

    def delta(self, x, ctx, rng=None):
        return self.delta_on_grid(x.shape[0], ctx.dt_s, _need_rng(rng, self.kind))

    def delta_on_grid(self, n, dt_s, rng):
        steps = rng.standard_normal((3, n))  # (3, N): cumsum along contiguous rows
        steps[:, 0] = 0.0
        np.cumsum(steps, axis=1, out=steps)
        steps *= (self.value * math.sqrt(dt_s))[:, None]
        return steps.T

    def ieee952_terms(self):
        return {"rate_random_walk": self.value}

    def coarse_step_s(self, white_density, dt_s):
        # K²/(2πf)² ≤ 0.01 N²  ⇔  f ≥ 10 K / (2π N)
        if np.any(white_density <= 0):
            return None
        f_min = float(np.max(10 * self.value / (2 * math.pi * white_density)))
        return 1.0 / (2.0 * f_min) if f_min > 0 else None

    noise_parameters: ClassVar[tuple[str, ...]] = ("value",)
    noise_short_name: ClassVar[str] = "rw"
    noise_bias_drift: ClassVar[bool] = True
    noise_rank: ClassVar[int] = 3
    noise_si_units: ClassVar[dict[str, str]] = {"gyro": "rad/s^2/sqrt(Hz)", "accelerometer": "m/s^3/sqrt(Hz)"}
    noise_datasheet_units: ClassVar[dict[str, str]] = {"gyro": "deg/h/sqrt(h)", "accelerometer": "ug/sqrt(h)"}

    @classmethod
    def noise_units(cls, field, value, rate_hz, triad):
        # two-sided PSD K² of the bias derivative (Kalibr random_walk), per sample σ = K √Δt
        out = {
            "continuous_two_sided (Kalibr random_walk)": value,
            "discrete_sigma_per_sample": value * math.sqrt(1.0 / rate_hz),
        }
        out.update(
            {"deg/h/sqrt(h)": value / DEG * 3600 * 60} if triad == "gyro" else {"ug/sqrt(h)": value / G0 * 1e6 * 60}
        )
        return out

    def haar_wavelet_variance(self, m, dt_s):
        # increments γ² = K²Δt; ν² = γ² (2m² + 1)/(12 m) (sum of squared weights of the increments
        # in a Haar coefficient, m(2m² + 1)/3, over (2m)²)
        m = np.asarray(m, float)[None, :]
        return (self.value**2 * dt_s)[:, None] * (2 * m * m + 1) / (12 * m)

    def discrete_psd(self, f_cyc, dt_s):
        s2 = np.sin(np.pi * np.asarray(f_cyc, float)) ** 2
        return (self.value**2 * dt_s)[:, None] / (4 * np.maximum(s2, 1e-300))[None, :]


@dataclass(frozen=True)
class GaussMarkov(Effect):
    """First-order Gauss–Markov (exponentially correlated) bias: stationary σ (rate or
    acceleration units) and correlation time τ (s) per axis; continuous ḃ = −b/τ + w with
    two-sided driving PSD q = 2σ²/τ; exact discretisation b_{k+1} = φ b_k + σ√(1 − φ²) w_k,
    φ = e^{−Δt/τ} (Maybeck 1979 §4.11).  A sensor model may hold several (GMWM's "2 GM" model).
    ``bias_instability`` with ``model = "gauss_markov"`` is this process sized by B (σ = B/0.664)."""

    kind: ClassVar[str] = "gauss_markov"
    quantities: ClassVar[dict[str, str]] = ANY_TRIAD
    stochastic: ClassVar[bool] = True
    invertible: ClassVar[bool] = False
    param_fields: ClassVar[tuple[str, ...]] = ("sigma", "tau_s")
    noise_parameters: ClassVar[tuple[str, ...]] = ("sigma", "tau_s")
    noise_short_name: ClassVar[str] = "gm"
    noise_rank: ClassVar[int] = 4
    noise_si_units: ClassVar[dict[str, str]] = {"gyro": "rad/s", "accelerometer": "m/s^2"}
    noise_datasheet_units: ClassVar[dict[str, str]] = {"gyro": "deg/h", "accelerometer": "ug"}

    @classmethod
    def noise_units(cls, field, value, rate_hz, triad):
        if field == "tau_s":  # correlation time, and the discrete φ = e^{−Δt/τ}
            return {"s": value, "discrete_phi": math.exp(-(1.0 / rate_hz) / value)}
        out = {"stationary_sigma": value}
        out.update({"deg/h": value / DEG * 3600} if triad == "gyro" else {"ug": value / G0 * 1e6})
        return out
    sigma: np.ndarray = field(default_factory=lambda: np.zeros(3))
    tau_s: np.ndarray = field(default_factory=lambda: np.full(3, 100.0))

    def __post_init__(self) -> None:
        v = _vec(self.sigma, name="Gauss-Markov sigma")
        t = _vec(self.tau_s, name="Gauss-Markov tau_s")
        if np.any(v < 0) or np.any(t <= 0):
            raise GyrosimError(f"gauss_markov needs sigma >= 0 and tau_s > 0 s, got {v.tolist()}, {t.tolist()}")
        object.__setattr__(self, "sigma", v)
        object.__setattr__(self, "tau_s", t)

    def delta(self, x, ctx, rng=None):
        return self.delta_on_grid(x.shape[0], ctx.dt_s, _need_rng(rng, self.kind))

    def delta_on_grid(self, n, dt_s, rng):
        return _ar1_draw(n, dt_s, self.sigma, self.tau_s, rng)

    def coarse_step_s(self, white_density, dt_s):
        # PSD 2σ²τ/(1 + (2πfτ)²) ≤ 2σ²/(τ(2πf)²) ≤ 0.01 N²  ⇔  f ≥ √(200 σ²/τ)/(2π N)
        if np.any(white_density <= 0):
            return None
        f_min = float(np.max(np.sqrt(200 * self.sigma**2 / self.tau_s) / (2 * math.pi * white_density)))
        return 1.0 / (2.0 * f_min) if f_min > 0 else None

    def haar_wavelet_variance(self, m, dt_s):
        return _ar1_haar(m, dt_s, self.sigma, self.tau_s)

    def discrete_psd(self, f_cyc, dt_s):
        phi = np.exp(-dt_s / self.tau_s)[:, None]
        c = np.cos(2 * np.pi * np.asarray(f_cyc, float))[None, :]
        return (self.sigma**2)[:, None] * (1 - phi**2) / (1 - 2 * phi * c + phi**2)


@dataclass(frozen=True)
class QuantizationNoise(Effect):
    """IEEE Std 952 quantization noise Q: white noise of variance Q² on the *integrated* output
    (angle rad, velocity m/s), so the rate sample is y_k += (e_k − e_{k−1})/Δt, e ~ N(0, Q²);
    σ_A(τ) = √3 Q/τ.  The statistical model of an integrating sensor's output counts (Gaussian
    here: only second moments enter the Allan and wavelet variances).  Not the ``quantization``
    output effect, which rounds each sample to its LSB."""

    kind: ClassVar[str] = "quantization_noise"
    quantities: ClassVar[dict[str, str]] = {"gyro": "angle", "accelerometer": "velocity"}
    stochastic: ClassVar[bool] = True
    invertible: ClassVar[bool] = False
    param_fields: ClassVar[tuple[str, ...]] = ("value",)
    noise_parameters: ClassVar[tuple[str, ...]] = ("value",)
    noise_short_name: ClassVar[str] = "qn"
    noise_rank: ClassVar[int] = 1
    noise_si_units: ClassVar[dict[str, str]] = {"gyro": "rad", "accelerometer": "m/s"}
    noise_datasheet_units: ClassVar[dict[str, str]] = {"gyro": "arcsec", "accelerometer": "mm/s"}
    value: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @classmethod
    def noise_units(cls, field, value, rate_hz, triad):
        # per rate sample σ = √2 Q f_s (the difference of two angle errors over Δt)
        out = {"Q": value, "discrete_sigma_per_sample": math.sqrt(2) * value * rate_hz}
        out.update({"arcsec": value / DEG * 3600} if triad == "gyro" else {"mm/s": value * 1e3})
        return out

    def __post_init__(self) -> None:
        v = _vec(self.value, name="quantization noise Q")
        if np.any(v < 0):
            raise GyrosimError("quantization noise Q must be >= 0")
        object.__setattr__(self, "value", v)

    def delta(self, x, ctx, rng=None):
        e = _need_rng(rng, self.kind).standard_normal((x.shape[0] + 1, 3)) * self.value
        return np.diff(e, axis=0) / ctx.dt_s

    def haar_wavelet_variance(self, m, dt_s):
        # a Haar coefficient of the rate is (2e_m − e_0 − e_2m)/(2mΔt): ν² = 6Q²/(2mΔt)²
        m = np.asarray(m, float)[None, :]
        return (6 * self.value**2)[:, None] / (2 * m * dt_s) ** 2

    def discrete_psd(self, f_cyc, dt_s):
        s2 = np.sin(np.pi * np.asarray(f_cyc, float)) ** 2
        return (self.value**2 / dt_s**2)[:, None] * (4 * s2)[None, :]


@dataclass(frozen=True)
class RateRamp(Effect):
    """IEEE Std 952 rate ramp R: a deterministic drift of the bias, δ = R (t − t₀) (rad/s², m/s³);
    σ_A(τ) = R τ/√2 (GMWM's "drift").  The wavelet variance sees R² only, so a fit gives |R|."""

    kind: ClassVar[str] = "rate_ramp"
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate_ramp", "accelerometer": "acceleration_ramp"}
    param_fields: ClassVar[tuple[str, ...]] = ("value",)
    noise_parameters: ClassVar[tuple[str, ...]] = ("value",)
    noise_short_name: ClassVar[str] = "drift"
    noise_bias_drift: ClassVar[bool] = True
    noise_rank: ClassVar[int] = 5
    noise_si_units: ClassVar[dict[str, str]] = {"gyro": "rad/s^2", "accelerometer": "m/s^3"}
    noise_datasheet_units: ClassVar[dict[str, str]] = {"gyro": "deg/h^2", "accelerometer": "ug/h"}
    value: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @classmethod
    def noise_units(cls, field, value, rate_hz, triad):
        out = {"R": value}
        out.update({"deg/h^2": value / DEG * 3600**2} if triad == "gyro" else {"ug/h": value / G0 * 1e6 * 3600})
        return out

    def __post_init__(self) -> None:
        object.__setattr__(self, "value", _vec(self.value, name="rate ramp"))

    def delta(self, x, ctx, rng=None):
        return (ctx.t_s - ctx.t_s[0])[:, None] * self.value[None, :]

    def sensitivity(self, x, ctx):
        return (ctx.t_s - ctx.t_s[0])[:, None, None] * np.eye(3)[None]

    def haar_wavelet_variance(self, m, dt_s):
        # a line of slope RΔt per sample: (S₂ − S₁)/(2m) = RΔt m/2
        m = np.asarray(m, float)[None, :]
        return (self.value**2 * dt_s**2)[:, None] * m * m / 4

    def discrete_psd(self, f_cyc, dt_s):
        return np.zeros((3, np.size(f_cyc)))  # deterministic: adds nothing to the estimator's variance
