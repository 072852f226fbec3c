"""Evidence: bridge sampling and nested sampling against a closed form, and each other."""

from __future__ import annotations

import warnings

import emcee
import numpy as np
import pytest
import scipy.special

from bayes_jackal import InputError, load_profile
from bayes_jackal.inference import FitOptions, ProcessExecutor
from bayes_jackal.inference.chains import SamplerSettings
from bayes_jackal.inference.comparison import Comparison, compare_families
from bayes_jackal.inference.evidence import (
    bridge_sampling,
    evidence_strength,
    integrated_time,
    nested_sampling,
)
from bayes_jackal.inference.sampler_warnings import ConvergenceWarning
from bayes_jackal.io.simulate import NoiseSettings, simulate_experiment
from bayes_jackal.likelihood import LikelihoodOptions
from bayes_jackal.likelihood.priors import LogPosterior, Prior
from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood
from bayes_jackal.posterior.records import Evidence

ROBOT = load_profile()
#: The yaw channel alone: these tests' statistics were tuned on it (the
#: default is every channel; tests/test_recovery_real.py tests that).
YAW = ("yaw",)


class WhiteOneStepRegression:
    """White-noise one-step residuals of the yaw rate, linear in their coefficients.

    y[k+1] = a y[k] + b (omega_r - omega_l)[k] + e[k], e ~ N(0, sigma^2): the
    thesis' eq. 7-3 residual with (Ad, Bd) as free coefficients. With a and
    b uniform on a box that holds the posterior and sigma log-uniform, the
    evidence has a closed form (:meth:`log_evidence`).
    """

    def __init__(self, experiment, sigma_range=(1e-4, 1.0)):
        yaw = experiment.yaw_rate
        self.y = yaw[1:]
        self.x = np.column_stack([yaw[:-1], (experiment.omega_r - experiment.omega_l)[:-1]])
        self.fit, *_ = np.linalg.lstsq(self.x, self.y, rcond=None)
        gram = self.x.T @ self.x
        sd = np.sqrt(np.diag(np.linalg.inv(gram)) * self.rss / len(self.y))
        # 12 posterior sds either side: the box truncates 4e-33 of the mass,
        # and stays positive for the sampler's log coordinates.
        low, high = self.fit - 12 * sd, self.fit + 12 * sd
        self.prior = Prior(
            ("a", "b", "sigma"),
            np.array([*low, sigma_range[0]]),
            np.array([*high, sigma_range[1]]),
            np.array([False, False, True]),
        )

    @property
    def rss(self) -> float:
        return float(np.sum((self.y - self.x @ self.fit) ** 2))

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        theta = np.atleast_2d(theta)
        residuals = self.y - theta[:, :2] @ self.x.T
        sigma = theta[:, 2]
        n = len(self.y)
        return (
            -0.5 * np.sum(residuals**2, axis=1) / sigma**2
            - n * np.log(sigma)
            - 0.5 * n * np.log(2 * np.pi)
        )

    def log_evidence(self) -> float:
        """log Z in closed form.

        Integrating the Gaussian in (a, b) gives (2 pi sigma^2)^(k/2)
        det(X'X)^(-1/2) exp(-RSS / (2 sigma^2)) times the box's density; the
        remaining integral over the log-uniform sigma is an incomplete gamma
        function in u = RSS / (2 sigma^2), with m = N - k.
        """
        n, k = self.x.shape
        m = n - k
        low, high = self.prior.low, self.prior.high
        volume = np.prod(high[:2] - low[:2])
        u_low, u_high = self.rss / (2 * high[2] ** 2), self.rss / (2 * low[2] ** 2)
        mass = scipy.special.gammainc(m / 2, u_high) - scipy.special.gammainc(m / 2, u_low)
        return float(
            -np.log(volume)
            - np.log(np.log(high[2] / low[2]))
            - 0.5 * m * np.log(2 * np.pi)
            - 0.5 * np.linalg.slogdet(self.x.T @ self.x)[1]
            + np.log(0.5)
            - 0.5 * m * np.log(self.rss / 2)
            + scipy.special.gammaln(m / 2)
            + np.log(mass)
        )


@pytest.fixture(scope="module")
def white_regression():
    noise = NoiseSettings(family="white", sigma_n=(0.0, 0.0, 0.0))
    return WhiteOneStepRegression(simulate_experiment(ROBOT, 110.0, 30.0, "v2", noise, rng=11))


def _emcee_chain(log_posterior, centre, seed, steps=2000, walkers=24):
    """A real emcee chain (burn-in and thinning as the package does)."""
    rng = np.random.default_rng(seed)
    start = centre + 1e-4 * rng.standard_normal((walkers, len(centre)))
    sampler = emcee.EnsembleSampler(walkers, len(centre), log_posterior, vectorize=True)
    moves_state = np.random.RandomState(seed).get_state()
    sampler.run_mcmc(emcee.State(start, random_state=moves_state), steps)
    tau = np.max(sampler.get_autocorr_time(tol=0))
    discard, thin = int(5 * tau), max(1, int(tau / 2))
    return sampler.get_chain(discard=discard, thin=thin), sampler.get_log_prob(
        discard=discard, thin=thin
    )


def test_bridge_sampling_matches_the_closed_form_within_its_error(white_regression):
    model = white_regression
    log_posterior = LogPosterior(model, model.prior)
    centre = np.log([*model.fit, np.sqrt(model.rss / len(model.y))])
    exact = model.log_evidence()
    z_scores = []
    for seed in range(4):
        chain, lp = _emcee_chain(log_posterior, centre, seed)
        estimate = bridge_sampling(log_posterior, chain, lp, rng=seed)
        # ~1,000 kept draws of a 3-parameter posterior: stated errors were
        # 0.016-0.020 over 12 chains; 0.05 flags an error estimate gone wrong.
        assert estimate.error < 0.05
        z_scores.append((estimate.log_evidence - exact) / estimate.error)
    # A calibrated error makes each z ~ N(0, 1): |z| < 4 fails with
    # probability 6e-5 per run; the mean of 4 has sd 0.5, |mean| < 2 (4 sd).
    assert np.all(np.abs(z_scores) < 4), z_scores
    assert abs(np.mean(z_scores)) < 2, z_scores


def test_bridge_sampling_recomputes_the_density_when_not_given(white_regression):
    model = white_regression
    log_posterior = LogPosterior(model, model.prior)
    centre = np.log([*model.fit, np.sqrt(model.rss / len(model.y))])
    chain, lp = _emcee_chain(log_posterior, centre, 0, steps=600)
    given = bridge_sampling(log_posterior, chain, lp, rng=1)
    recomputed = bridge_sampling(log_posterior, chain, None, rng=1)
    assert recomputed.log_evidence == pytest.approx(given.log_evidence, abs=1e-9)


def test_nested_sampling_matches_the_closed_form_within_its_error(white_regression):
    model = white_regression
    estimate = nested_sampling(model, model.prior, rng=3, live_points=300)
    # dynesty's error is the sd of log Z; 4 sd fails once in 16,000 runs.
    assert abs(estimate.log_evidence - model.log_evidence()) < 4 * estimate.error
    # Its error is about sqrt(H / live points) = 0.24 here (H ~ 17 nats of
    # information); 0.5 keeps the check above from passing on a vague estimate.
    assert estimate.error < 0.5


def test_bridge_sampling_rejects_a_short_or_misshapen_chain():
    with pytest.raises(InputError, match="draws >= 8"):
        bridge_sampling(lambda z: -np.sum(z**2, axis=1), np.zeros((4, 8, 2)))
    with pytest.raises(InputError, match="draws >= 8"):
        bridge_sampling(lambda z: -np.sum(z**2, axis=1), np.zeros((40, 2)))


def test_bridge_sampling_survives_a_walker_stuck_through_the_chain():
    # A walker that never moves, far in the tail (seen in a moving-average
    # chain), has a bridge function constant to the last bit, whose
    # autocorrelation is undefined (emcee divided by zero: a RuntimeWarning,
    # an error here): it counts as fully correlated, so the error grows.
    chain = np.random.default_rng(1).normal(size=(200, 8, 2))
    log_density = lambda x: -0.5 * np.sum(x**2, axis=-1)  # noqa: E731
    mixed = bridge_sampling(log_density, chain, rng=1)
    chain[:, 0] = 30.0
    stuck = bridge_sampling(log_density, chain, rng=1)
    assert np.isfinite(stuck.log_evidence) and stuck.error > 3 * mixed.error


def test_integrated_time_is_emcee_s_and_counts_a_stuck_walker_as_one_draw():
    rng = np.random.default_rng(4)
    walks = np.cumsum(rng.normal(size=(300, 6)), axis=0)  # tau ~ 40
    assert integrated_time(walks) == pytest.approx(
        emcee.autocorr.integrated_time(walks, tol=0)[0], rel=1e-12
    )
    # Reference, walker by walker: emcee's normalised autocorrelation of each
    # moving walker, 1 at every lag for the stuck one; averaged, summed to
    # the first lag beyond 5 tau (the whole series where there is none).
    walks[:, 2] = 7.0
    curves = [np.ones(300) if np.ptp(w) == 0 else emcee.autocorr.function_1d(w) for w in walks.T]
    taus = 2 * np.cumsum(np.mean(curves, axis=0)) - 1
    window = next((m for m in range(300) if m >= 5 * taus[m]), 299)
    assert integrated_time(walks) == pytest.approx(taus[window], rel=1e-12)
    assert integrated_time(np.full((50, 4), 2.0)) == 99.0  # all stuck: 2 m - 1


def test_kass_raftery_words():
    assert evidence_strength(0.5) == "not worth more than a bare mention"
    assert evidence_strength(-2.0) == "positive"
    assert evidence_strength(4.0) == "strong"
    assert evidence_strength(30.0) == "very strong"


@pytest.mark.parametrize(
    ("white", "coloured", "label"),
    [
        ((100.0, 0.1), (120.0, 0.1), "coloured"),
        ((100.0, 0.1), (101.5, 0.1), "inconclusive"),
        # 4 nats but an error of 1 each: 4 - 2 * 1.41 < 3 stays inconclusive.
        ((100.0, 1.0), (104.0, 1.0), "inconclusive"),
        ((100.0, 0.1), (98.0, 0.1), "not coloured"),
    ],
)
def test_verdict_rules(white, coloured, label):
    comparison = Comparison(
        ["run"],
        {
            "white": Evidence(*white, "test"),
            "gaussian": Evidence(*coloured, "test"),
        },
        {},
    )
    assert comparison.verdict()[0] == label


def test_white_beating_the_families_compared_is_not_coloured_only_where_its_fit_holds():
    # A 1 kHz physics-engine log (issue 37, item 14): white beat gaussian by
    # ln B = 159 while the white fit missed the residuals' colour and the
    # exponential family, not compared, beat white by thousands. White's own
    # predictive-acf warning makes "not coloured" inconclusive, naming the
    # families to add; a "not coloured" names those not compared.
    evidence = {"white": Evidence(100.0, 0.1, "test"), "gaussian": Evidence(98.0, 0.1, "test")}
    comparison = Comparison(["run"], evidence, {})
    label, sentence = comparison.verdict(["predictive-acf"])
    assert label == "inconclusive" and "the white fit misses the residuals' colour" in sentence
    assert "compare exponential, triangular, moving-average too" in sentence
    label, sentence = comparison.verdict([])
    assert label == "not coloured"
    assert sentence.endswith("(exponential, triangular, moving-average not compared)")


def test_unknown_or_repeated_families_are_refused():
    run = simulate_experiment(ROBOT, 110.0, 30.0, "v2", rng=1)
    for families in (("gaussian", "pink"), ("white", "white"), ()):
        with pytest.raises(InputError, match="families"):
            compare_families([run], FitOptions(robot=ROBOT), families=families)


@pytest.mark.slow
def test_bridge_and_nested_sampling_agree_on_coloured_noise():
    run = simulate_experiment(ROBOT, 110.0, 30.0, "v2", rng=4)
    options = FitOptions(robot=ROBOT, likelihood_options=LikelihoodOptions(channels=YAW), seed=2)
    comparison = compare_families([run], options, families=("gaussian",))
    bridge = comparison.evidence["gaussian"]
    likelihood = ResidualLikelihood([run], ROBOT, family="gaussian", channels=YAW)
    # 100 live points: about 45,000 likelihood calls one by one (dynesty's
    # random walks; 200 took 88,000 and 2 minutes), an error of ~0.7 nats.
    nested = nested_sampling(
        likelihood, Prior.for_likelihood(likelihood, ROBOT), rng=5, live_points=100, dlogz=0.5
    )
    # Independent estimates: their difference has sd sqrt(e1^2 + e2^2); 3 sd.
    assert abs(bridge.log_evidence - nested.log_evidence) < 3 * np.hypot(
        bridge.error, nested.error
    )


#: The family test's noise: widths of 0.15 s (11 samples) over sensor noise
#: 5x below the process noise let the families' autocorrelation shapes show.
#: (The moving-average fit still meets spectral nulls no spectral grid
#: certifies: on Gaussian data ~14,000 parameter sets, which the banded
#: Cholesky fallback evaluates in ~14 s; the Durbin-Levinson recursion it
#: replaced took ~250 s, bayes_jackal/toeplitz.py.)
DISTINCT = {"width": 0.15, "sigma_c": (0.005, 0.005, 0.02), "sigma_n": (0.003, 0.003, 0.004)}
#: Chains capped at 600 steps (~10 tau): bridge sampling counts their
#: autocorrelation, and the margins below are tens of nats.
CAPPED = SamplerSettings(max_steps=600, autocorr_multiple=10, design_points=512)


def _compare(noise: NoiseSettings, seed: int) -> Comparison:
    run = simulate_experiment(ROBOT, 110.0, 30.0, "v1", noise, rng=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        options = FitOptions(
            robot=ROBOT,
            likelihood_options=LikelihoodOptions(channels=YAW),
            settings=CAPPED,
            seed=seed,
        )
        return compare_families([run], options)


@pytest.mark.slow
@pytest.mark.parametrize("family", ["gaussian", "exponential", "triangular", "moving-average"])
def test_the_true_family_has_the_highest_evidence(family):
    comparison = _compare(NoiseSettings(family=family, **DISTINCT), seed=5)
    assert comparison.best == family, comparison.to_dict()["families"]
    runner_up = max(
        (name for name in comparison.evidence if name != family),
        key=lambda name: comparison.evidence[name].log_evidence,
    )
    value, error = comparison.log_bayes_factor(family, runner_up)
    # Measured margins over the runner-up: tens to hundreds of nats.
    assert value - 3 * error > 3, (runner_up, value, error)
    assert comparison.verdict()[0] == "coloured"


@pytest.mark.slow
@pytest.mark.parametrize("seed", [5, 6])
def test_white_noise_is_never_called_coloured(seed):
    # Every coloured family contains white noise; the Occam factor of its
    # width favours white by only ~1-2 nats, so 'inconclusive' is allowed.
    comparison = _compare(NoiseSettings(family="white"), seed)
    assert comparison.verdict()[0] in ("not coloured", "inconclusive")
    coloured = max(v.log_evidence for k, v in comparison.evidence.items() if k != "white")
    assert coloured - comparison.evidence["white"].log_evidence < 3


def test_families_in_parallel_processes_give_the_same_result():
    run = simulate_experiment(ROBOT, 110.0, 30.0, "v2", rng=1)
    quick = SamplerSettings(max_steps=100, design_points=256)
    results = []
    for processes in (1, 2):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ConvergenceWarning)
            comparison = compare_families(
                [run],
                FitOptions(
                    robot=ROBOT,
                    likelihood_options=LikelihoodOptions(channels=YAW),
                    settings=quick,
                    seed=3,
                ),
                families=("white", "gaussian"),
                executor=ProcessExecutor(processes),
            )
        results.append(comparison)
        # Both chains stop at the cap; each worker's warning reaches the caller.
        assert sorted(str(w.message).split(":")[0] for w in caught) == ["gaussian", "white"]
    serial, parallel = results
    assert list(parallel.evidence) == ["white", "gaussian"]
    for family in ("white", "gaussian"):
        assert parallel.evidence[family] == serial.evidence[family]
