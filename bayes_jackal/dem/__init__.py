"""The prior for Active Inference (DEM) filters, exported from a posterior, and
the file it is written to.
"""

from .consumer_keys import (
    channel_moments,
    continuous_sd,
    gaussian_smoothness,
    generalised_precision,
    log_precision_moments,
    matrix_prior,
    mean_covariance_precision,
    operating_point,
)
from .export import (
    MAX_CONDITION,
    allowed_orders,
    autocorrelation_derivatives,
    checked_precision,
    checked_sensor_smoothness,
    export_prior,
    read_prior,
    temporal_covariance,
    write_prior,
)
from .prior import ActiveInferencePrior
from .prior_fields import PRIOR_FORMAT, check_prior_fields, prior_field, prior_layout

__all__ = [
    "MAX_CONDITION",
    "PRIOR_FORMAT",
    "ActiveInferencePrior",
    "allowed_orders",
    "autocorrelation_derivatives",
    "channel_moments",
    "check_prior_fields",
    "checked_precision",
    "checked_sensor_smoothness",
    "continuous_sd",
    "export_prior",
    "gaussian_smoothness",
    "generalised_precision",
    "log_precision_moments",
    "matrix_prior",
    "mean_covariance_precision",
    "operating_point",
    "prior_field",
    "prior_layout",
    "read_prior",
    "temporal_covariance",
    "write_prior",
]
