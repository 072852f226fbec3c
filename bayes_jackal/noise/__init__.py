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

__all__ = [
    "MIN_SERIES_SAMPLES",
    "NOISE_PRIOR_FORMAT",
    "RECORD_FRACTION",
    "ROS2_METADATA",
    "SD_RANGE",
    "SERIES_PRIOR_KEYS",
    "TIME_NAMES",
    "WIDTH_FLOOR",
    "FamilyFit",
    "NoiseCharacterisation",
    "NoiseSeries",
    "characterise_noise",
    "export_noise_prior",
    "fit_family",
    "read_noise_series",
    "series_prior",
    "series_prior_overrides",
]
