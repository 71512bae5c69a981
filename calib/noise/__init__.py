"""Noise identification beyond Allan slopes: Haar wavelet variance, GMWM fit of a
composite model of the effect vocabulary's noise terms, WIC model selection, intervals, units,
record-length planning and the noise-inflation figure.  Modules: :mod:`.wavelet`, :mod:`.gmwm`,
:mod:`.identify`, :mod:`.units`, :mod:`.inflation`, :mod:`.plan`."""

from calib.noise.gmwm import NOISE_TERMS, candidate_models, identify_axis, model_name, parse_model
from calib.noise.identify import NoiseIdentification, identify_noise, minimum_samples
from calib.noise.wavelet import WaveletVariance, wavelet_variance

__all__ = ["NOISE_TERMS", "candidate_models", "identify_axis", "model_name", "parse_model", "NoiseIdentification",
           "identify_noise", "minimum_samples", "WaveletVariance", "wavelet_variance"]
