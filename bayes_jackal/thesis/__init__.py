"""The thesis' own methods: the grid searches over the damping (ch. 5-6) and the
residual analysis of ch. 7.
"""

from .acf_fit import LEAST_SQUARES_LAGS, THESIS_LAGS, acf_least_squares, thesis_fit
from .gridsearch import (
    GridResult,
    damping_grid,
    grid_search,
    onestep_mse,
    prior_grid,
    simulation_mse,
)
from .residual_analysis import (
    FIRST_LAGS,
    SIGMA_H_GRID,
    analyse,
    average_per_series,
    fit_sigma_h,
    sigma_h_table,
)

#: What a user of this stage needs (the API reference); the other names
#: imported above serve the package's later stages.
__all__ = [
    "acf_least_squares",
    "analyse",
    "damping_grid",
    "grid_search",
    "prior_grid",
    "thesis_fit",
]
