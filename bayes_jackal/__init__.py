"""bayes_jackal: Bayesian system identification of skid-steer mobile robots.

The public names are imported on first use (PEP 562), so that importing the
package, e.g. for ``bayes-jackal --version``, does not load numpy and scipy.
"""

from __future__ import annotations

import importlib

#: The one place the version is kept: pyproject.toml reads it from here.
__version__ = "0.1.0"

#: Public name -> the subpackage that exports it.
_LAZY = {
    # the workflow: logs in, posteriors, evidence, priors, reports out
    "load_experiments": ".io",
    "sample": ".inference",
    "compare": ".inference",
    # many runs: groups, their population and its speed dependence
    "population": ".inference",
    "Population": ".inference",
    "read_groups": ".io",
    "plot_population": ".report",
    "export_prior": ".dem",
    "write_prior": ".dem",
    "read_prior": ".dem",
    "ActiveInferencePrior": ".dem",
    "write_report": ".report",
    "analyse_logs": ".workflow",
    # a bare noise series
    "NoiseSeries": ".noise",
    "characterise_noise": ".noise",
    "export_noise_prior": ".noise",
    "read_noise_series": ".noise",
    "write_noise_report": ".report",
    # state estimation with a prior (the filters)
    "FILTERS": "._runtime.defaults",
    "estimate_columns": ".filters",
    "estimate_each": ".filters",
    "estimate_states": ".filters",
    "generalised_filter": ".filters",
    "kalman_filter": ".filters",
    "score_estimates": ".filters",
    "write_estimates": ".filters",
    # what it takes and gives
    "Comparison": ".inference",
    "ConvergenceWarning": ".inference",
    "Experiment": ".io",
    "FAMILIES": ".model",
    "NoiseSettings": ".io",
    "RobotProfile": ".model",
    "SamplerSettings": ".inference",
    "Posterior": ".posterior",
    "load_posterior": ".posterior",
    "load_profile": ".model",
    "packaged_profiles": ".model",
    "save_posterior": ".posterior",
    "simulate_experiment": ".io",
    "summarize": ".posterior",
    "write_csv": ".io",
    # errors
    "DataError": "._runtime.errors",
    "InputError": "._runtime.errors",
    "OutputError": "._runtime.errors",
    "ProfileError": "._runtime.errors",
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
