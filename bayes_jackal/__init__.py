"""bayes_jackal: Bayesian system identification of skid-steer mobile robots."""

from .errors import DataError, InputError, ProfileError
from .robot import RobotProfile, load_profile

__version__ = "0.1.0"

__all__ = [
    "DataError",
    "InputError",
    "ProfileError",
    "RobotProfile",
    "__version__",
    "load_profile",
]
