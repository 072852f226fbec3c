"""bayes_jackal: Bayesian system identification of skid-steer mobile robots.

The public names are imported on first use (PEP 562), so that importing the
package, e.g. for ``bayes-jackal --version``, does not load numpy and scipy.
"""

from __future__ import annotations

from ._runtime import lazy_exports

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
    "read_groups": ".io",
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
    "FILTERS": "._runtime",
    "estimate_states": ".filters",
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
    "DataError": "._runtime",
    "InputError": "._runtime",
    "OutputError": "._runtime",
    "ProfileError": "._runtime",
}

__all__ = ["__version__", *sorted(_LAZY)]


#: The stages, reached as ``bj.io``, ``bj.filters`` ...: each offers in its
#: ``__all__`` what a user of that stage needs beyond the names above.
_STAGES = (
    "dem",
    "filters",
    "inference",
    "io",
    "likelihood",
    "model",
    "noise",
    "posterior",
    "report",
    "thesis",
    "workflow",
)

__getattr__, __dir__ = lazy_exports(__name__, _LAZY, _STAGES)
