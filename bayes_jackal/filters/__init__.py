"""State estimation with an exported prior: Kalman filters, the generalised (DEM D-step)
filter, and each run estimated with the prior of the others.
"""

from .generalised import (
    TAIL,
    conditional_covariance,
    d_step,
    generalised_filter,
    process_precision,
)
from .generalised_coordinates import (
    embed,
    embedding_operator,
    shift_operator,
    taylor_step,
    white_sensor_precision,
)
from .kalman_filters import (
    CONVERGED,
    DIFFUSE,
    KALMAN_FILTERS,
    TRUNCATION,
    StateEstimate,
    kalman,
    kalman_filter,
)
from .left_out import FOLDER, METHODS, SUMMARY, LeaveOneOut, leave_one_out, method_text
from .lti import lti_outputs, matrix_powers
from .state_estimation import (
    DERIVED,
    FILTER_INEXACT,
    NIS_DRAWS,
    NIS_PROBABILITY,
    estimate_columns,
    estimate_each,
    estimate_states,
    inexact_note,
    nis_band,
    score_estimates,
    score_rows,
    write_estimates,
)
from .state_space import (
    NOISE_MODELS,
    PARAMETERS,
    PRIOR_RATE_TOLERANCE,
    ChannelModel,
    channel_model,
    check_prior,
    filter_models,
    measured_series,
    noise_parameters,
    parameter_values,
    prior_robot,
)

#: What a user of this stage needs (the API reference); the other names
#: imported above serve the package's later stages.
__all__ = [
    "StateEstimate",
    "estimate_columns",
    "estimate_states",
    "generalised_filter",
    "kalman_filter",
    "leave_one_out",
    "score_estimates",
    "write_estimates",
]
