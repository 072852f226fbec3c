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
    MAX_DRAWS,
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

#: What a user of this stage needs (the API reference); the other names
#: imported above serve the package's later stages.
__all__ = [
    "ActiveInferencePrior",
    "export_prior",
    "operating_point",
    "read_prior",
    "temporal_covariance",
    "write_prior",
]
