"""Discriminative correlation filters (thesis ch. 3): MOSSE, the continuous C-COT filter and the PSR.

Shared by point tracking (2D patches) and horizon localisation (1D profiles). Signals are real tensors whose
last ``ndim`` axes are the signal and whose leading axes are a batch of independent filters. Signals are in
FFT order: the target (and the label peak) sits at index 0 of every signal axis, so a response peak at index
``i`` is a circular shift of ``i`` (wrapped to ``[-N/2, N/2)``).
"""

from models.dcf.continuous import (
    CcotFilter,
    ccot_filter,
    ccot_sample,
    ccot_train,
    ccot_update,
    continuous_label,
    cubic_spline_fourier,
    exponential_forgetting_weights,
    fourier_series_peak,
    shift_fourier,
)
from models.dcf.mosse import (
    Mosse,
    gaussian_label,
    mosse_filter,
    mosse_response,
    mosse_train,
    mosse_update,
)
from models.dcf.noise import ImageNoiseStd, image_noise_std
from models.dcf.peak import response_peak
from models.dcf.preprocess import DcfPreprocess, cosine_window, dcf_preprocess, tukey_window
from models.dcf.psr import PeakToSidelobeRatio, peak_to_sidelobe_ratio

__all__ = [
    "CcotFilter",
    "DcfPreprocess",
    "ImageNoiseStd",
    "Mosse",
    "PeakToSidelobeRatio",
    "ccot_filter",
    "ccot_sample",
    "ccot_train",
    "ccot_update",
    "continuous_label",
    "cosine_window",
    "cubic_spline_fourier",
    "dcf_preprocess",
    "exponential_forgetting_weights",
    "fourier_series_peak",
    "gaussian_label",
    "image_noise_std",
    "mosse_filter",
    "mosse_response",
    "mosse_train",
    "mosse_update",
    "peak_to_sidelobe_ratio",
    "response_peak",
    "shift_fourier",
    "tukey_window",
]
