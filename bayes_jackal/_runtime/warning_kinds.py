"""The kinds of warning, one vocabulary: the ``kind`` of every warning the JSON,
the report and the command line carry, from every check.

A kind is a lower-case phrase with hyphens. :data:`KIND_MEANINGS` says in a
phrase what each means for the result (the CLI's summary line, the report).
"""

from __future__ import annotations

__all__ = [
    "COVARIATE_INCOMPLETE",
    "DAMPING_SCALE_NOT_IDENTIFIED",
    "DERIVED_VELOCITY",
    "FEW_GROUPS",
    "GRID_EDGE",
    "INPUT_NOISE",
    "KIND_MEANINGS",
    "NORMAL_SUMMARY",
    "NOT_CONVERGED",
    "NOT_STEADY",
    "ONE_OPERATING_POINT",
    "OTHER_WARNING",
    "PREDICTIVE_ACF",
    "PRIOR_BOUNDARY",
    "PRIOR_SENSITIVITY",
    "RESIDUAL_INPUT",
]

#: A chain stopped at its step cap before its convergence criterion held.
NOT_CONVERGED = "not-converged"
#: A parameter's draws are piled at (or reach) its prior's bound.
PRIOR_BOUNDARY = "prior-boundary"
#: The runs fix d_lat/d_long, not the damping's scale.
DAMPING_SCALE_NOT_IDENTIFIED = "damping-scale-not-identified"
#: The residuals correlate with the wheel speeds.
RESIDUAL_INPUT = "residual-input"
#: White noise on the wheel speeds (taken as exact).
INPUT_NOISE = "input-noise"
#: The fitted noise does not reproduce the residuals' autocorrelation.
PREDICTIVE_ACF = "predictive-acf"
#: An analysed window is not steady cornering.
NOT_STEADY = "not-steady"
#: Velocities derived from poses, modelled as measured.
DERIVED_VELOCITY = "derived-velocity"
#: A grid search's minimum on the grid's edge.
GRID_EDGE = "grid-edge"
#: A population unit's draws are not summarised well by a normal.
NORMAL_SUMMARY = "normal-summary"
#: Fewer than 3 groups in a population.
FEW_GROUPS = "few-groups"
#: Another spread prior moves the population's mean.
PRIOR_SENSITIVITY = "prior-sensitivity"
#: Every population unit at one covariate value: no slope fitted.
ONE_OPERATING_POINT = "one-operating-point"
#: A covariate given for some runs only: no slope fitted.
COVARIATE_INCOMPLETE = "covariate-incomplete"
#: Any other Python warning kept with a result.
OTHER_WARNING = "warning"

#: What each kind of warning means for the result, in a phrase (the CLI's summary line).
KIND_MEANINGS = {
    NOT_CONVERGED: "a chain stopped before its criterion held: its numbers are preliminary",
    PRIOR_BOUNDARY: "a parameter is piled at its prior's bound: the data give only a limit",
    DAMPING_SCALE_NOT_IDENTIFIED: (
        "the runs fix the ratio d_lat/d_long, not the damping's scale: report the ratio"
    ),
    RESIDUAL_INPUT: "the residuals follow the wheel speeds: a dynamic or input is missing",
    INPUT_NOISE: "white noise on the wheel speeds, taken as exact, biases the damping low",
    PREDICTIVE_ACF: "the fitted noise misses the residuals' colour: try another family",
    NOT_STEADY: "an analysed window is not steady cornering, which the model assumes",
    DERIVED_VELOCITY: "velocities derived from poses are modelled as measured: damping biased",
}
