"""The DEM prior of a noise series: V and Pi in seconds and bins, orders, the file, the command."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest

from bayes_jackal._runtime.errors import InputError
from bayes_jackal.cli import main
from bayes_jackal.dem.export import MAX_CONDITION, MAX_DRAWS, write_prior
from bayes_jackal.model.kernels import get_family
from bayes_jackal.noise.characterisation import FamilyFit, NoiseCharacterisation
from bayes_jackal.noise.prior import NOISE_PRIOR_FORMAT, export_noise_prior
from bayes_jackal.noise.series import NoiseSeries
from bayes_jackal.posterior.records import Evidence

DT = 0.01
#: Posterior draws of the made-up fits: a width of 3 bins and sds spread by 20 %.
DRAWS = 400


def lognormal(rng: np.random.Generator, centre: float, spread: float = 0.2) -> np.ndarray:
    return centre * np.exp(spread * rng.standard_normal(DRAWS))


def family_fit(
    family: str, columns: dict[str, np.ndarray], log_evidence: float, dt: float = DT
) -> FamilyFit:
    """A fit of made-up draws (no sampling), its parameters named as the package names them."""
    return FamilyFit(
        family=family,
        names=tuple(columns),
        draws=np.column_stack(list(columns.values())),
        evidence=Evidence(log_evidence, 0.1, "bridge sampling"),
        diagnostics={"converged": True},
        warnings=[],
        dt=dt,
    )


@pytest.fixture(scope="module")
def result() -> NoiseCharacterisation:
    """White, Gaussian, triangular and exponential fits; the Gaussian has the highest evidence."""
    rng = np.random.default_rng(5)

    def coloured(width_name: str) -> dict:
        return {width_name: lognormal(rng, 3 * DT), "sigma_c": lognormal(rng, 1.0),
                "sigma_n": lognormal(rng, 0.3)}  # fmt: skip

    fits = [
        family_fit("white", {"sigma": lognormal(rng, 1.05)}, -950.0),
        family_fit("gaussian", coloured("sigma_h"), -900.0),
        family_fit("triangular", coloured("width"), -905.0),
        family_fit("exponential", coloured("width"), -910.0),
    ]
    series = NoiseSeries(values=rng.standard_normal(200), dt=DT, name="gyro")
    return NoiseCharacterisation(
        series=series,
        fits={fit.family: fit for fit in fits},
        acf_least_squares={1: 0.03},
        thesis_fit=0.03,
    )


def column(fit: FamilyFit, name: str) -> np.ndarray:
    return fit.draws[:, fit.names.index(name)]


def gaussian_rho(s: float, order: int) -> np.ndarray:
    """rho^(n)(0), n = 0 .. 2 order, of exp(-t^2 / (4 s^2)): SPM's closed form
    rho^(2k)(0) = (-1)^k (2k - 1)!! / (2 s^2)^k (spm_DEM_R), odd ones zero."""
    rho = np.zeros(2 * order + 1)
    for m in range(order + 1):
        rho[2 * m] = (-1) ** m * np.prod(np.arange(1, 2 * m, 2)) / (2 * s**2) ** m
    return rho


def triangular_rho(w: float, order: int) -> np.ndarray:
    """rho(0), rho'(0), rho''(0) of the triangular filter of half-width w: rho''(0) =
    -int h'^2 / int h^2 = -(2 / w) / (2 w / 3) = -3 / w^2 for h(t) = 1 - |t| / w (order <= 1)."""
    return np.array([1.0, 0.0, -3 / w**2])[: 2 * order + 1]


def covariance(rho: np.ndarray) -> np.ndarray:
    """V[i, j] = (-1)^i rho^(i+j)(0), written out."""
    n = (len(rho) + 1) // 2
    return np.array([[(-1) ** i * rho[i + j] for j in range(n)] for i in range(n)])


def spm_dem_r(n: int, s: float) -> np.ndarray:
    """spm_DEM_R(n, s): inv(V) of the Gaussian form, s in time bins."""
    return np.linalg.inv(covariance(gaussian_rho(s, n - 1)))


def close(actual, expected) -> None:
    """Equal to rounding: two closed forms inverted apart, relative 1e-10 of the largest entry."""
    expected = np.asarray(expected)
    np.testing.assert_allclose(actual, expected, rtol=1e-10, atol=1e-10 * np.abs(expected).max())


@pytest.mark.parametrize("order", [1, 2, 3])
def test_gaussian_bins_are_spm_dem_r(result, order):
    # In bins the Gaussian family's V is SPM's, at the smoothness sigma_h / dt.
    coordinates = export_noise_prior(result, order=order)["generalised_coordinates"]
    bins = column(result.fits["gaussian"], "sigma_h") / DT
    R = [spm_dem_r(order + 1, s) for s in bins]
    close(coordinates["temporal_precision_bins"], np.mean(R, axis=0))
    close(coordinates["temporal_covariance_bins"], np.mean(np.linalg.inv(R), axis=0))


@pytest.mark.parametrize(("family", "rho", "order"), [
    ("gaussian", gaussian_rho, 2),
    ("triangular", triangular_rho, 1),
])  # fmt: skip
def test_precision_is_the_mean_over_draws(result, family, rho, order):
    fit = result.fits[family]
    width, sigma_c = fit.draws[:, 0], column(fit, "sigma_c")
    V = [covariance(rho(w, order)) for w in width]
    precision = np.mean([np.linalg.inv(v) / s**2 for v, s in zip(V, sigma_c, strict=True)], 0)
    mean_covariance = np.mean([v * s**2 for v, s in zip(V, sigma_c, strict=True)], axis=0)
    prior = export_noise_prior(result, family=family, order=order)
    coordinates = prior["generalised_coordinates"]
    assert coordinates["order"] == order and prior["sigma_c_is"] == "coloured"
    close(coordinates["temporal_covariance"], np.mean(V, axis=0))
    close(coordinates["precision"], precision)
    close(coordinates["precision_mean_covariance"], np.linalg.inv(mean_covariance))
    # Jensen: the mean precision exceeds the precision of the mean covariance.
    assert coordinates["precision"][0][0] > coordinates["precision_mean_covariance"][0][0]


@pytest.mark.parametrize("family", ["gaussian", "triangular"])
def test_bins_are_seconds_with_derivatives_scaled_by_dt(result, family):
    # Derivative i in bins is dt^i times the one in seconds; the noise is not a
    # rate, so its sd is the same in both units.
    coordinates = export_noise_prior(result, family=family, order=None)["generalised_coordinates"]
    k = np.arange(coordinates["order"] + 1)
    scale = DT ** np.add.outer(k, k)
    for name in ("precision", "precision_mean_covariance", "temporal_precision"):
        close(coordinates[f"{name}_bins"], np.asarray(coordinates[name]) / scale)
    close(
        coordinates["temporal_covariance_bins"],
        np.asarray(coordinates["temporal_covariance"]) * scale,
    )


def test_best_family_by_default_and_its_parts(result):
    prior = export_noise_prior(result, source="gyro.csv")
    assert prior["format"] == NOISE_PRIOR_FORMAT and prior["source"] == "gyro.csv"
    assert prior["family"] == prior["best"] == "gaussian" and prior["verdict"] == "coloured"
    assert prior["series"] == {"name": "gyro", "source": "<memory>", "samples": 200}
    assert prior["dt"] == DT and prior["bayes_jackal_version"]
    assert prior["fit"]["log_bayes_factor_vs_white"] == pytest.approx(50.0)
    fit = result.fits["gaussian"]
    sigma_h, sigma_n = column(fit, "sigma_h"), column(fit, "sigma_n")
    assert prior["fit"]["width"]["bins"]["mean"] == pytest.approx(sigma_h.mean() / DT)
    # The Gaussian family's smoothness is its width; the floor's precision is E[1 / sigma_n^2].
    assert prior["smoothness"]["bins"]["mean"] == pytest.approx(sigma_h.mean() / DT)
    assert prior["white_floor"]["precision"]["mean"] == pytest.approx(np.mean(sigma_n**-2))
    assert prior["log_precision"]["white_floor"]["mean"] == pytest.approx(
        np.mean(-2 * np.log(sigma_n))
    )
    assert prior["generalised_coordinates"]["order"] == 2  # AUTO_ORDER, which it allows
    assert prior["draws"]["count"] == DRAWS and prior["draws"]["sigma_h"] == sigma_h.tolist()


@pytest.mark.parametrize(("family", "expected"), [("white", 0), ("exponential", 0),
                                                 ("triangular", 1), ("gaussian", 2)])  # fmt: skip
def test_the_default_order_is_two_or_the_highest_allowed(result, family, expected):
    # order=None is the default, as `noise --order`: whichever family is best
    # by evidence, the prior is exported (a white best family gives order 0).
    prior = export_noise_prior(alone(result.fits[family], result.series))
    assert prior["generalised_coordinates"]["order"] == expected
    assert (prior["smoothness"] is None) == (expected == 0)
    again = export_noise_prior(result, family=family, order=None)
    assert again["generalised_coordinates"] == prior["generalised_coordinates"]


def test_white_family_is_all_of_the_noise(result):
    prior = export_noise_prior(result, family="white", order=0)
    sigma = column(result.fits["white"], "sigma")
    assert prior["sigma_c_is"] == "total" and prior["white_floor"] is None
    close(prior["generalised_coordinates"]["precision"], [[np.mean(sigma**-2)]])
    close(
        prior["generalised_coordinates"]["precision_mean_covariance_bins"],
        [[1 / np.mean(sigma**2)]],
    )


@pytest.mark.parametrize(("family", "order", "pattern"), [
    ("white", 1, "up to order 0, got 1"),
    ("exponential", 1, "up to order 0, got 1"),
    ("triangular", 2, "up to order 1, got 2"),
    ("gaussian", -1, "integer >= 0"),
    ("gaussian", 30, r"order 30 gives a precision .* allowed here are 0, 1, 2(, \d)*$"),
])  # fmt: skip
def test_orders_the_family_cannot_give_are_refused(result, family, order, pattern):
    with pytest.raises(InputError, match=rf"order: .*{pattern}"):
        export_noise_prior(result, family=family, order=order, source="gyro.csv")


def alone(fit: FamilyFit, series: NoiseSeries) -> NoiseCharacterisation:
    """A characterisation of one family's fit."""
    return NoiseCharacterisation(series=series, fits={fit.family: fit}, acf_least_squares={},
                                 thesis_fit=0.03)  # fmt: skip


def test_moving_average_gives_order_zero_only(result):
    columns = dict(zip(result.fits["exponential"].names, result.fits["exponential"].draws.T,
                       strict=True))  # fmt: skip
    moving = alone(family_fit("moving-average", columns, -1.0), result.series)
    assert export_noise_prior(moving, order=None)["generalised_coordinates"]["order"] == 0
    with pytest.raises(InputError, match=r"order: .*up to order 0"):
        export_noise_prior(moving, order=1)
    with pytest.raises(InputError, match="family: no 'gaussian' fit"):
        export_noise_prior(moving, family="gaussian")


def test_the_file_round_trips_and_the_draws_are_thinned(result, tmp_path):
    n = 2500
    columns = {"width": np.full(n, 0.03), "sigma_c": np.random.default_rng(8).uniform(0.9, 1.1, n),
               "sigma_n": np.full(n, 0.3)}  # fmt: skip
    many = family_fit("exponential", columns, -1.0)
    before = many.draws.copy()
    for prior in (
        export_noise_prior(result),
        export_noise_prior(alone(many, result.series), order=0),
    ):
        path = write_prior(prior, tmp_path / "gyro.prior.json")
        assert json.loads(path.read_text()) == prior
    assert prior["draws"]["count"] == MAX_DRAWS and len(prior["draws"]["sigma_c"]) == MAX_DRAWS
    np.testing.assert_array_equal(many.draws, before)  # the characterisation is not changed


def condition(rho: np.ndarray) -> float:
    """The condition number of inv(V), V written out from rho^(n)(0)."""
    return np.linalg.cond(np.linalg.inv(covariance(rho)))


@pytest.mark.parametrize(("width", "dt", "allowed"), [
    (0.001, 0.001, [0, 1]),  # a 1 kHz IMU, 1 bin: seconds refuse order 2 (1.13e12; bins 3.9)
    (0.5, 0.01, [0, 1, 2, 3]),  # 50 bins: bins refuse order 4 (3e13; seconds 2e9 at order 8)
])  # fmt: skip
def test_orders_are_checked_in_seconds_and_in_bins(width, dt, allowed):
    # The file holds Pi in seconds and in bins: every order it gives has both
    # condition numbers below MAX_CONDITION, and the next one (and order 8) is
    # refused, naming both (export.MAX_CONDITION says why both).
    rng = np.random.default_rng(11)
    columns = {"sigma_h": np.full(DRAWS, width), "sigma_c": lognormal(rng, 1.0),
               "sigma_n": lognormal(rng, 0.3)}  # fmt: skip
    series = NoiseSeries(values=rng.standard_normal(200), dt=dt, name="imu")
    imu = alone(family_fit("gaussian", columns, -1.0, dt=dt), series)
    assert export_noise_prior(imu)["generalised_coordinates"]["order"] == min(2, allowed[-1])
    for order in allowed:
        coordinates = export_noise_prior(imu, order=order)["generalised_coordinates"]
        assert max(coordinates["condition"], coordinates["condition_bins"]) < MAX_CONDITION
    listed = ", ".join(map(str, allowed))
    for order in (8, allowed[-1] + 1):  # the first refused order last: its numbers below
        with pytest.raises(InputError, match=rf"order: order {order} gives a precision with "
                           rf"condition number \S+ in seconds, \S+ in bins .*allowed here are "
                           rf"{listed}$") as refused:  # fmt: skip
            export_noise_prior(imu, order=order)
    # Its numbers: inv(V) at the width in seconds and in bins.
    numbers = str(refused.value).split("number ")[1].split(" (")[0]
    seconds, bins = (condition(gaussian_rho(s, order)) for s in (width, width / dt))
    assert numbers == f"{seconds:.3g} in seconds, {bins:.3g} in bins"
    assert (seconds < MAX_CONDITION) == (width > dt)  # a width of many bins: bins refuse


def test_the_noise_command_writes_the_best_familys_prior(tmp_path, capsys):
    # One run, two series, `--order 2`. The gyro's best family, Gaussian noise of
    # width 2 bins over a white floor of sd 0.3 (characterise_noise's example),
    # gives its prior, with a warning: 16 steps are far from converged. The
    # accelerometer's is white noise, which has no derivative: a warning and no
    # prior, its <series>.noise.json written all the same, exit 0 (docs/active_inference.md).
    rng = np.random.default_rng(7)
    gyro = np.convolve(rng.standard_normal(600), get_family("gaussian").taps(0.02, DT), "same")
    gyro += 0.3 * rng.standard_normal(600)
    accel = np.random.default_rng(8).standard_normal(600)
    paths = []
    for name, values in [("gyro", gyro), ("accel", accel)]:
        paths.append(tmp_path / f"{name}.csv")
        np.savetxt(paths[-1], np.column_stack([np.arange(600) * DT, values]), delimiter=",",
                   header=f"time,{name}", comments="")  # fmt: skip
    before = [hashlib.sha256(path.read_bytes()).hexdigest() for path in paths]
    out = tmp_path / "results"
    flags = ["--families", "white,gaussian", "--seed", "1", "--no-progress", "--processes", "1"]
    code = main(["noise", *map(str, paths), *flags, "--max-steps", "16", "--order", "2",
                 "--out", str(out)])  # fmt: skip
    printed = capsys.readouterr()
    assert code == 0 and f"wrote {out / 'gyro.prior.json'}" in printed.out
    prior = json.loads((out / "gyro.prior.json").read_text())
    noise = json.loads((out / "gyro.noise.json").read_text())
    assert prior["format"] == NOISE_PRIOR_FORMAT and prior["family"] == noise["best"] == "gaussian"
    assert prior["generalised_coordinates"]["order"] == 2 and prior["source"] == str(paths[0])
    assert prior["fit"] == noise["families"]["gaussian"] and prior["converged"] is False
    assert (
        "bayes-jackal: WARNING: gyro's gaussian fit is NOT CONVERGED; the prior inherits that"
        in printed.err
    )
    assert json.loads((out / "accel.noise.json").read_text())["best"] == "white"
    assert "WARNING: no prior for accel: order: " in printed.err
    assert "up to order 0, got 2" in printed.err and not (out / "accel.prior.json").exists()
    assert [hashlib.sha256(path.read_bytes()).hexdigest() for path in paths] == before
