"""Posteriors built without sampling, for tests of what reads a posterior.

Imported by the test modules (as tests/reliability_cases.py is): a
posterior concentrated around chosen parameters, built by
:func:`bayes_jackal.posterior.build_inference_data` as a sampled one is.
"""

from __future__ import annotations

import numpy as np

from bayes_jackal import load_profile
from bayes_jackal.likelihood.priors import Prior
from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood
from bayes_jackal.posterior.posterior import build_inference_data

ROBOT = load_profile()


def posterior_at(
    experiments,
    theta,
    family="gaussian",
    channels=("yaw",),
    spread=0.02,
    shared_width=False,
    sensor="ma1",
    steady=False,
):
    """A posterior concentrated around theta (log-normal spread), built as a sampled one is.

    ``steady``: the likelihood on each run's steady window (the thesis' crop), not every sample.
    """
    likelihood = ResidualLikelihood(
        experiments, ROBOT, family=family, channels=channels, shared_width=shared_width,
        sensor=sensor, steady=steady,
    )  # fmt: skip
    prior = Prior.for_likelihood(likelihood, ROBOT)
    z = np.log(theta) + spread * np.random.default_rng(8).normal(size=(40, 8, len(theta)))
    names = prior.names
    diagnostics = {
        "converged": True,
        "n_steps": 40,
        "autocorr_time": dict.fromkeys(names, 1.0),
        "ess_autocorr": dict.fromkeys(names, 320.0),
    }
    return build_inference_data(likelihood, prior, z, np.zeros((40, 8)), diagnostics)
