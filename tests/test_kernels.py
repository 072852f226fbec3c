"""Noise-filter families: kernels, exact autocorrelations, PSDs and generators."""

import warnings

import numpy as np
import pytest

import bayes_jackal as bj
from bayes_jackal import InputError, load_profile
from bayes_jackal.dem.export import autocorrelation_derivatives
from bayes_jackal.inference.sampler_warnings import ConvergenceWarning
from bayes_jackal.io.simulate import NoiseSettings, simulate_experiment
from bayes_jackal.likelihood.priors import Prior
from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood
from bayes_jackal.model.kernels import FAMILIES, Family, bandwidth, gaussian_kernel, get_family

DT = 1.0 / 72.0
#: Widths [s] below one sample, at a whole Gaussian tap count (3 w / dt = 10) and between.
WIDTHS = np.array([0.004, 10 * DT / 3, 0.047, 0.1, 0.5])
FINITE = ["white", "gaussian", "triangular", "moving-average"]


def autocorrelation(kernel: np.ndarray, lags: int) -> np.ndarray:
    """Reference: a kernel's self-correlation sum_j h[j] h[j + l], one width at a time."""
    full = np.correlate(kernel, kernel, mode="full")[len(kernel) - 1 :]
    out = np.zeros(lags)
    out[: min(lags, len(full))] = full[:lags]
    return out


def bartlett_sd(rho: np.ndarray, lag: int, n: int) -> float:
    """Standard deviation of the sample autocorrelation at ``lag`` (Bartlett's formula)."""
    full = np.concatenate([rho[:0:-1], rho, np.zeros(lag)])
    centre = len(rho) - 1
    j = np.arange(-centre, centre + 1)
    terms = full[centre + j + lag] + full[centre + j - lag] - 2 * rho[lag] * full[centre + j]
    return float(np.sqrt(np.sum(terms**2) / n))


def eq_7_5(sigma_h: float, k: np.ndarray) -> np.ndarray:
    """The thesis' Gaussian filter (eq. 7-5) at t = k dt, with its analytic prefactor."""
    t = k * DT
    return np.sqrt(DT / (sigma_h * np.sqrt(np.pi))) * np.exp(-(t**2) / (2 * sigma_h**2))


def test_gaussian_kernel_is_eq_7_5_where_its_tap_count_is_whole():
    # 3 sigma_h / dt = 10: taps k = -10..10, exactly the thesis' truncation.
    sigma_h = 10 * DT / 3
    kernel = gaussian_kernel(sigma_h, DT)
    assert np.sum(kernel**2) == pytest.approx(1.0, rel=1e-14)
    # In floating point 3 sigma_h / dt is 10 + 2e-15, so the edge taps |k| = 11
    # may be present with weight 2e-15: zero to 1e-16.
    assert len(kernel) in (21, 23)
    k = np.arange(len(kernel)) - len(kernel) // 2
    expected = np.where(np.abs(k) <= 10, eq_7_5(sigma_h, k), 0.0)
    # The analytic prefactor misses only the truncated tail, erfc(3) ~ 2.2e-5 of the energy.
    np.testing.assert_allclose(kernel, expected, rtol=2e-5, atol=1e-16)
    with pytest.raises(InputError, match="sigma_h"):
        gaussian_kernel(-0.1, DT)


def test_gaussian_kernel_weights_its_edge_taps_by_the_fractional_tap_count():
    # Table 7-1's 0.047 s: 3 sigma_h / dt = 10.152. Taps |k| <= 10 are eq. 7-5;
    # the two at |k| = 11 are eq. 7-5 times 0.152, so that a tap enters at zero
    # height as sigma_h grows, not at exp(-4.5) of the peak (which made the
    # likelihood jump: tests/test_likelihood.py).
    sigma_h = 0.047
    fraction = 3 * sigma_h / DT - 10
    kernel = gaussian_kernel(sigma_h, DT)
    assert len(kernel) == 23
    k = np.arange(-11, 12)
    expected = eq_7_5(sigma_h, k) * np.where(np.abs(k) == 11, fraction, 1.0)
    np.testing.assert_allclose(kernel, expected, rtol=2e-5)
    # For sigma_h << dt the kernel is one tap (white noise): at 0.001 s the
    # edge taps are 0.22 exp(-96) ~ 1e-43 of it.
    np.testing.assert_allclose(gaussian_kernel(0.001, DT), [0.0, 1.0, 0.0], rtol=0, atol=1e-40)


def test_gaussian_autocorrelation_approaches_the_continuous_form():
    # White noise through h has autocorrelation exp(-tau^2 / (4 sigma_h^2)) in
    # the continuous limit (docs/design.md §3). Sampling errors are exponentially small
    # for sigma_h >> dt; what remains is the +-3 sigma_h truncation, which is
    # scale-free and moves the self-correlation by about 3e-3 at any width.
    for sigma_h in (0.047, 0.1, 0.2):
        rho = FAMILIES["gaussian"].autocorrelation(sigma_h, DT, 60)
        tau = np.arange(60) * DT
        np.testing.assert_allclose(rho, np.exp(-(tau**2) / (4 * sigma_h**2)), atol=5e-3)


@pytest.mark.parametrize("name", FINITE)
def test_vectorised_autocorrelation_matches_a_per_width_self_correlation(name):
    family = FAMILIES[name]
    rho = family.autocorrelation(WIDTHS, DT, 200)
    assert rho.shape == (len(WIDTHS), 200)
    for width, row in zip(WIDTHS, rho, strict=True):
        taps = np.trim_zeros(family.taps(width, DT))
        assert np.sum(taps**2) == pytest.approx(1.0, rel=1e-13)
        np.testing.assert_allclose(row, autocorrelation(taps, 200), rtol=0, atol=1e-13)


@pytest.mark.parametrize("name", FINITE[1:])
def test_autocorrelation_ends_at_each_kernels_length_whatever_the_batch(name):
    # A narrow kernel batched with a wide one (padded to its taps): the
    # transform's rounding past the narrow kernel's length is dropped, so
    # its band (what the banded factor takes) is its own, not the batch's
    # (before: the wide one's). Within it, the FFT's rounding (1e-15).
    family = FAMILIES[name]
    narrow = len(np.trim_zeros(family.taps(0.05, DT)))
    batched = family.autocorrelation(np.array([0.05, 0.5]), DT, 200)
    alone = family.autocorrelation(0.05, DT, 200)
    assert bandwidth(batched[0]) == bandwidth(alone) == narrow < bandwidth(batched[1])
    np.testing.assert_allclose(batched[0], alone, rtol=0, atol=1e-15)


def test_closed_forms_of_the_exponential_moving_average_and_triangular_families():
    lags = np.arange(40)
    # AR(1): rho = exp(-l dt / tau).
    tau = 0.05
    np.testing.assert_allclose(
        FAMILIES["exponential"].autocorrelation(tau, DT, 40), np.exp(-lags * DT / tau), rtol=1e-14
    )
    # A boxcar of L whole samples: rho = (1 - l / L)+.
    L = 7
    np.testing.assert_allclose(
        FAMILIES["moving-average"].autocorrelation(L * DT, DT, 40),
        np.clip(1 - lags / L, 0, None),
        atol=1e-14,
    )
    # A triangle of half-base m samples has taps 1 - |k|/m, |k| < m; its
    # energy is (2 m^2 + 1) / (3 m).
    m = 5
    taps = FAMILIES["triangular"].taps(m * DT, DT)
    np.testing.assert_allclose(
        np.trim_zeros(taps) * np.sqrt((2 * m**2 + 1) / (3 * m)),
        1 - np.abs(np.arange(-m + 1, m)) / m,
        atol=1e-14,
    )
    assert FAMILIES["white"].autocorrelation(0.1, DT, 5).tolist() == [1, 0, 0, 0, 0]


def _largest_step(name: str, points: int) -> tuple[float, np.ndarray, np.ndarray]:
    widths = np.linspace(0.02, 0.2, points)
    steps = np.abs(np.diff(FAMILIES[name].autocorrelation(widths, DT, 30), axis=0)).max(axis=1)
    return steps.max(), steps, widths


@pytest.mark.parametrize("name", ["moving-average", "triangular", "gaussian"])
def test_autocorrelation_is_continuous_in_the_width(name):
    # A continuous rho(width) has steps that shrink with the grid spacing
    # (10x finer grid: ~10x smaller steps); a jump would not shrink. The
    # grid 0.02..0.2 s crosses 39 Gaussian tap boundaries (3 w / dt whole)
    # and 13 of the others (w / dt whole).
    coarse, _, _ = _largest_step(name, 2001)
    fine, _, _ = _largest_step(name, 20001)
    assert fine < coarse / 5


@pytest.mark.parametrize("name", list(FAMILIES))
def test_psd_is_the_transform_of_the_autocorrelation_and_integrates_to_one(name):
    family = FAMILIES[name]
    width = 0.06
    frequency = np.linspace(-36.0, 36.0, 4001)
    psd = family.psd(width, DT, frequency)
    rho = family.autocorrelation(width, DT, 2000)
    lags = np.arange(1, 2000)
    omega = 2 * np.pi * frequency * DT
    from_rho = DT * (rho[0] + 2 * np.cos(np.outer(omega, lags)) @ rho[1:])
    np.testing.assert_allclose(psd, from_rho, rtol=1e-9, atol=1e-12)
    # Parseval: the variance, 1 (trapezoid on 4001 points over a smooth periodic function).
    assert np.trapezoid(psd, frequency) == pytest.approx(1.0, rel=1e-6)


@pytest.mark.parametrize("name", list(FAMILIES))
def test_filtered_white_noise_has_the_stated_autocorrelation(name):
    family = FAMILIES[name]
    n, lags = 300_000, 15
    noise = family.noise(0.047, DT, n, scale=np.array([2.0, 0.5]), rng=42)
    assert noise.shape == (n, 2)
    rho = family.autocorrelation(0.047, DT, 400)
    sd = np.array([bartlett_sd(rho, k, n) for k in range(lags)])
    for column, scale in zip(noise.T, (2.0, 0.5), strict=True):
        # Sample variance: its sd is scale^2 sqrt(2 sum rho^2 / n) < 1 % here.
        assert np.var(column) == pytest.approx(scale**2, rel=0.05)
        centred = column - column.mean()
        sample = np.array([centred[: n - k] @ centred[k:] for k in range(lags)])
        sample /= centred @ centred
        # 5 sd per lag: with 15 lags a false alarm has probability < 1e-5.
        np.testing.assert_array_less(np.abs(sample - rho[:lags]), 5 * sd + 1e-12)


@pytest.mark.parametrize("name", ["gaussian", "exponential"])
def test_same_seed_same_noise(name):
    family = FAMILIES[name]
    first = family.noise(0.047, DT, 100, rng=3)
    np.testing.assert_array_equal(first, family.noise(0.047, DT, 100, rng=3))
    assert not np.allclose(first, family.noise(0.047, DT, 100, rng=4))


def test_bad_family_and_widths_are_rejected():
    with pytest.raises(InputError, match="'pink'"):
        get_family("pink")
    for name in ("gaussian", "exponential", "triangular", "moving-average"):
        with pytest.raises(InputError, match=r"got -0\.1"):
            FAMILIES[name].autocorrelation(np.array([0.1, -0.1]), DT, 5)
        with pytest.raises(InputError, match="got nan"):
            FAMILIES[name].noise(np.nan, DT, 5)


class Boxcar(Family):
    """A sixth family, defined here only: the moving-average kernel renamed.

    Its own name and width name, and taps written independently of the
    package's, so that every number it gives has a reference: the
    moving-average family's.
    """

    name = "boxcar"
    width_name = "duration"
    description = "duration [s] of a boxcar filter"

    def _taps(self, width: np.ndarray, dt: float) -> np.ndarray:
        samples = np.maximum(width / dt, 1.0)[..., None]
        return np.clip(samples - np.arange(int(np.ceil(samples.max()))), 0.0, 1.0)


def test_a_family_registered_in_families_needs_no_other_change(monkeypatch):
    # docs/families.md: a new family is a Family subclass and a FAMILIES entry.
    # The simulator, the parameter layout, the priors, the likelihood and the
    # export then take it by name, each through the registry alone.
    monkeypatch.setitem(FAMILIES, "boxcar", Boxcar())
    robot = load_profile()
    run = simulate_experiment(
        robot, 110.0, 30.0, "v1", NoiseSettings(width=0.1, family="boxcar"), rng=5
    )
    assert run.truth["duration"] == run.truth["width"] == 0.1
    channels = ("yaw", "vx")
    likelihood = ResidualLikelihood([run], robot, family="boxcar", channels=channels)
    assert likelihood.layout.names == (
        "d_lat",
        "d_long",
        "duration[yaw]",
        "sigma_c[yaw]",
        "sigma_n[yaw]",
        "duration[vx]",
        "sigma_c[vx]",
        "sigma_n[vx]",
    )
    prior = Prior.for_likelihood(likelihood, robot, {"width": (0.02, 0.5)})
    np.testing.assert_array_equal(prior.low[[2, 5]], 0.02)
    # Two points: the truth-like one and a longer kernel with more sensor noise.
    theta = np.array(
        [
            [110.0, 30.0, 0.1, 0.01, 0.005, 0.1, 0.005, 0.003],
            [150.0, 40.0, 0.3, 0.02, 0.01, 0.05, 0.004, 0.006],
        ]
    )
    for engine in ("fast", "exact"):
        reference = ResidualLikelihood(
            [run], robot, family="moving-average", channels=channels, engine=engine
        )
        value = ResidualLikelihood([run], robot, family="boxcar", channels=channels, engine=engine)
        # Same kernel, taps written twice: they differ by rounding only, a few
        # ulps of log-likelihoods of ~1e4 nats; 1e-12 is far above that.
        np.testing.assert_allclose(value(theta), reference(theta), rtol=1e-12)
    assert autocorrelation_derivatives("boxcar", 0.1, 0).tolist() == [1.0]
    with pytest.raises(InputError, match=r"boxcar family.*up to order 0"):
        autocorrelation_derivatives("boxcar", 0.1, 1)
    # ... and compare, which hands out its measured families longest first:
    # one it has not measured goes first. 60 steps only exercise the path.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        comparison = bj.compare(
            run, families=("white", "boxcar"), channels=["yaw"], max_steps=60, seed=1
        )
    assert set(comparison.evidence) == {"white", "boxcar"}
    assert np.isfinite(comparison.evidence["boxcar"].log_evidence)
