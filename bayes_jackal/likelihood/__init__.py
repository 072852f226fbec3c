"""From an experiment to a log-likelihood: one-step residuals, how each channel was
measured, the likelihood engines (Toeplitz, spectral, Whittle) and the sampler's priors.
"""

from .irregular import (
    IrregularSeries,
    irregular_loglike,
    irregular_residuals,
    pattern_coefficients,
)
from .measurements import (
    BRIDGED_GAP,
    MEASUREMENT_MODELS,
    ChannelObservations,
    ChannelSeries,
    Measurement,
    PoseMeasurement,
    RateMeasurement,
    measurement_of,
    pose_weights,
    residual_autocovariance,
)
from .priors import LogPosterior, Prior
from .residual_likelihood import (
    LikelihoodOptions,
    ResidualLikelihood,
    pose_channels,
    resolve_channels,
    sample_stationary,
)
from .residuals import (
    channel_residuals,
    check_residual_window,
    residual_count,
    residual_regressors,
    residual_times,
)
from .series_likelihood import (
    MIN_LIKELIHOOD_SAMPLES,
    SERIES_SPREAD,
    WHITE_SD,
    SeriesLikelihood,
    check_length,
    check_series,
)
from .spectral import (
    CHUNK_ELEMENTS,
    SHORT_GRIDS,
    ResidualBlock,
    evaluate_on_grids,
    spectral_forms,
    spectral_loglike,
)
from .toeplitz import (
    FALLBACK_BAND,
    FAST_TOLERANCE,
    SCAN_WORK,
    banded_loglike,
    banded_toeplitz_loglike,
    fallback_loglike,
    toeplitz_loglike,
)
from .whittle import (
    cross_periodogram,
    debiased_whittle_loglike,
    expected_periodogram,
    frequency_weights,
)

#: What a user of this stage needs (the API reference); the other names
#: imported above serve the package's later stages.
__all__ = [
    "LikelihoodOptions",
    "Prior",
    "ResidualLikelihood",
    "channel_residuals",
]
