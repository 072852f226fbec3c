"""What a posterior is and says: the posterior file, its records and summary,
posterior-predictive series, model criticism and PSIS reweighting.
"""

from .criticism import (
    BOUNDARY_DENSITY,
    BOUNDARY_STRIP,
    PORTMANTEAU_LAGS,
    PREDICTIVE_ALARM,
    PREDICTIVE_DRAWS,
    PREDICTIVE_LAGS,
    PREDICTIVE_WINDOW,
    PRIOR_SHIFT,
    boundary_check,
    criticise,
    damping_scale,
    predictive_acf,
    prior_boundary,
)
from .criticism_inputs import (
    INPUTS,
    RESIDUAL_ACF_LAGS,
    RESIDUAL_INPUT_LAGS,
    RESIDUAL_INPUT_LEVEL,
    derived_velocities,
    input_noise,
    residual_input,
    steady_windows,
    velocities_derived,
)
from .criticism_statistics import (
    Check,
    acf_statistics,
    boundary_density,
    cross_correlation,
    cross_correlation_sd,
    predictive_flags,
    predictive_p_values,
    prior_shift,
    simultaneous_threshold,
    steadiness,
)
from .file_format import (
    FORMAT,
    READABLE_FORMATS,
    ROBOT_CONSTANTS,
    experiment_arrays,
    experiment_data,
    file_attributes,
    observed_data,
    observed_residuals,
    posterior_layout,
    store_comparison,
    store_criticism,
    store_reweighting,
)
from .posterior import (
    Posterior,
    build_inference_data,
    load_posterior,
    model_autocovariance,
    noise_dimension,
    save_posterior,
)
from .predictive import (
    CHUNK_SAMPLES,
    model_percentiles,
    predictive_series,
    predictive_statistics,
    stationary_series,
    stationary_statistics,
)
from .records import Convergence, Evidence, ExperimentRecord, PosteriorMetadata
from .reweighting import (
    OWN_COVARIANCE_SCALE,
    PARETO_K_THRESHOLD,
    PooledPosterior,
    RunWeights,
    conditional_log_density,
    psis_weights,
)
from .series_statistics import (
    MATLAB_LEVEL,
    WELCH_SEGMENT,
    autocorrelation_bounds,
    check_lags,
    ljung_box,
    magnitude_spectrum,
    sample_autocorrelation,
    spectrum,
)
from .summary import INTERVAL_FIELDS, THESIS_RATIO, Summary, interval, summarize

#: What a user of this stage needs (the API reference); the other names
#: imported above serve the package's later stages.
__all__ = [
    "Evidence",
    "Posterior",
    "Summary",
    "criticise",
    "interval",
    "load_posterior",
    "save_posterior",
    "spectrum",
    "summarize",
]
