"""bayes_jackal: Bayesian system identification of skid-steer mobile robots.

The public names are imported on first use (PEP 562), so that importing the
package, e.g. for ``bayes-jackal --version``, does not load numpy and scipy.
"""

from __future__ import annotations

import importlib

#: The one place the version is kept: pyproject.toml reads it from here.
__version__ = "0.1.0"

#: Public name -> the module that defines it.
_LAZY = {
    # the workflow (bayes_jackal.api): logs in, posteriors, evidence, priors, reports out
    "load_experiments": ".api",
    "sample": ".api",
    "compare": ".api",
    "export_prior": ".export",
    "write_prior": ".export",
    "read_prior": ".export",
    "write_report": ".report",
    "analyse_logs": ".workflow",
    # a bare noise series
    "NoiseSeries": ".noise_series",
    "characterise_noise": ".noise_characterisation",
    "export_noise_prior": ".noise_prior",
    "read_noise_series": ".noise_series",
    "write_noise_report": ".noise_report",
    # state estimation with a prior (the filters)
    "FILTERS": ".state_estimation",
    "estimate_columns": ".state_estimation",
    "estimate_each": ".state_estimation",
    "estimate_states": ".state_estimation",
    "generalised_filter": ".generalised_filtering",
    "kalman_filter": ".kalman",
    "score_estimates": ".state_estimation",
    "write_estimates": ".state_estimation",
    # what it takes and gives
    "Comparison": ".comparison_result",
    "ConvergenceWarning": ".sampler_warnings",
    "Experiment": ".experiment",
    "FAMILIES": ".kernels",
    "NoiseSettings": ".simulate",
    "RobotProfile": ".robot",
    "SamplerSettings": ".inference",
    "load_posterior": ".posterior",
    "load_profile": ".robot",
    "save_posterior": ".posterior",
    "simulate_experiment": ".simulate",
    "summarize": ".posterior",
    "write_csv": ".tables",
    # errors
    "DataError": ".errors",
    "InputError": ".errors",
    "OutputError": ".errors",
    "ProfileError": ".errors",
}

__all__ = ["__version__", *sorted(_LAZY)]


def __getattr__(name: str):
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(_LAZY[name], __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
