"""One vocabulary of sensor error effects: simulated by gyrosim, estimated by calib.

An :class:`Effect` is a named, parameterised term of a triad's measurement model.  Two stages:

* **error** effects add a term computed from the *true* input x (rate or specific force) and
  the context (the other triad's truth, temperature, attitude, magnetic field, time):

      y = x + Σ_i δ_i(x, ctx; θ_i)                          (Zhou 2020 eq. 1 for the first four)

  so their order does not matter and the classic linear model ω̃ = (I + S + N) ω + b + ε is the
  sum of the ``scale_factor``, ``nonorthogonality``, ``bias`` and ``white_noise`` terms;
* **output** effects then transform the sensor's output in order (bandwidth, latency, jitter,
  quantization, saturation): y ← T_j(y).

Every effect knows (a) how to corrupt (:meth:`Effect.delta` / :meth:`Effect.transform`), (b) how
the output depends on x (``delta_dx``, used to invert the model: compensation) and on its
parameters (:meth:`Effect.sensitivity`, used to fit it and to test it as a candidate against a
residual).  Stochastic effects (noise processes) draw from the ``numpy.random.Generator`` the
caller passes.  Random unit-to-unit parameters (turn-on bias, scale tolerance, ...) are given as
``<param>_sigma`` next to the nominal value and are drawn by :meth:`Effect.realize`.

Frames: x and δ in the body frame (RFU); the Earth rate uses the attitude body→ENU.  Parameters
are SI (rad/s, m/s², s, Hz, °C) except the magnetometer triad's, which are in µT like the
``Recording``; presets convert datasheet units with :mod:`gyrosim.units`.

The package, one module a stage: :mod:`~gyrosim.effects.base` (context, interface, registry),
:mod:`~gyrosim.effects.error_terms` (bias, scale, axes, nonlinearity, g-sensitivity),
:mod:`~gyrosim.effects.thermal`, :mod:`~gyrosim.effects.environment` (Earth rate, magnetic
sensitivity), :mod:`~gyrosim.effects.magnetometer` (hard/soft iron, frame rotation, attached magnet),
:mod:`~gyrosim.effects.noise` (random processes, IEEE 952 terms) and
:mod:`~gyrosim.effects.output` (output stage).  Each effect class declares what the rest of the
code asks of it (triads and unit quantities, display unit, white noise, closed-loop candidate and
regressor: :class:`Effect`) and registers itself in :data:`EFFECTS` by being defined; nothing
else switches on effect names.  A new effect is one class, in any module (a user's too).
"""

from __future__ import annotations

# modules in vocabulary order: EFFECTS lists the kinds in the order their classes are defined, so the import order is
# the vocabulary's order (the model loop proposes candidates in it): not sorted
# isort: off
from .base import EFFECTS, Effect, SignalContext, VectorEffect, effect_from_dict, unregister_effect, zeros_field
from .error_terms import (Bias, GSensitivity, GyroAccMisalignment, Misalignment, NonOrthogonality, ScaleAsymmetry,
                          ScaleFactor, ScaleNonlinearity, nonortho_matrix)
from .thermal import TemperatureBias, TemperaturePiecewise, TemperatureRBF, TemperatureScale, ThermalHysteresis
from .environment import EARTH_RATE_RAD_S, EarthRate, MagneticSensitivity
from .magnetometer import AttachedMagnet, FrameRotation, HardIron, SoftIron, rotation_matrix
from .noise import (BiasInstability, GaussMarkov, QuantizationNoise, RandomWalk, RateRamp, WhiteNoise, haar_gain2,
                    spectral_noise)
from .output import Bandwidth, Jitter, Quantization, Saturation, TimeOffset
# isort: on

__all__ = [
    "SignalContext", "Effect", "VectorEffect", "EFFECTS", "effect_from_dict", "unregister_effect", "zeros_field",
    "rotation_matrix", "nonortho_matrix", "spectral_noise", "haar_gain2", "EARTH_RATE_RAD_S",
    "Bias", "ScaleFactor", "NonOrthogonality", "Misalignment", "GyroAccMisalignment", "ScaleNonlinearity",
    "ScaleAsymmetry", "GSensitivity",
    "TemperatureBias", "TemperatureScale", "ThermalHysteresis", "TemperaturePiecewise", "TemperatureRBF",
    "EarthRate", "MagneticSensitivity", "HardIron", "SoftIron", "FrameRotation", "AttachedMagnet",
    "WhiteNoise", "BiasInstability", "RandomWalk", "GaussMarkov", "QuantizationNoise", "RateRamp",
    "Bandwidth", "TimeOffset", "Jitter", "Quantization", "Saturation",
]
