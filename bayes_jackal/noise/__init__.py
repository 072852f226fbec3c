"""A bare noise series: reading it, its families' posteriors and evidence, and its DEM prior."""

from .characterisation import (
    RECORD_FRACTION,
    SD_RANGE,
    SERIES_PRIOR_KEYS,
    WIDTH_FLOOR,
    FamilyFit,
    NoiseCharacterisation,
    characterise_noise,
    fit_family,
    series_prior,
    series_prior_overrides,
)
from .prior import NOISE_PRIOR_FORMAT, export_noise_prior
from .series import MIN_SERIES_SAMPLES, ROS2_METADATA, TIME_NAMES, NoiseSeries, read_noise_series

#: What a user of this stage needs (the API reference); the other names
#: imported above serve the package's later stages.
__all__ = [
    "NoiseCharacterisation",
    "NoiseSeries",
    "characterise_noise",
    "export_noise_prior",
    "read_noise_series",
]
