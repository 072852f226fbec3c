"""The robot and its model: robot profiles, the thesis' linear skid-steer physics,
the noise-filter families (kernels) and the parameter layout.
"""

from .kernels import (
    FAMILIES,
    Exponential,
    Family,
    Gaussian,
    MovingAverage,
    Triangular,
    White,
    bandwidth,
    gaussian_kernel,
    get_family,
)
from .parameters import (
    DAMPING,
    POSE_SENSOR,
    PRIOR_KEYS,
    RATE_SENSOR,
    SHARED_GROUP,
    SPEED_RATIO,
    SPEED_RATIO_PRIOR,
    SPEED_RATIOS,
    WIDTH_ALIAS,
    WIDTH_PRIOR,
    ParameterLayout,
    prior_overrides,
    prior_range,
    width_keys,
)
from .physics import (
    Method,
    channel_coefficients,
    continuous_matrices,
    discrete_matrices,
    discretise,
    one_step_prediction,
    one_step_residuals,
    propagate,
    simulate,
    step_integrals,
    wheel_speeds,
)
from .robot import (
    DEFAULT_PRIORS,
    PRIOR_REFERENCE_MASS,
    RobotProfile,
    as_profile,
    default_profile_path,
    load_profile,
    mass_scaled_damping,
    mass_scaled_priors,
    packaged_profiles,
)

#: What a user of this stage needs (the API reference); the other names
#: imported above serve the package's later stages.
__all__ = [
    "FAMILIES",
    "Family",
    "RobotProfile",
    "get_family",
    "load_profile",
    "packaged_profiles",
    "simulate",
]
