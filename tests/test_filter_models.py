"""The families' state-space realisations, the filter models of a prior, and bad priors."""

from __future__ import annotations

import dataclasses
import json
import re

import numpy as np
import pytest
import scipy.linalg
from synthetic_posteriors import posterior_at
from test_kalman import truth_prior

from bayes_jackal import load_profile
from bayes_jackal._runtime.errors import DataError, InputError
from bayes_jackal.dem.export import export_prior
from bayes_jackal.dem.prior_fields import check_prior_fields
from bayes_jackal.filters.state_space import channel_model, check_prior, filter_models
from bayes_jackal.io.simulate import simulate_experiment
from bayes_jackal.model.kernels import FAMILIES

ROBOT = load_profile()
DT = ROBOT.dt
#: Widths [s] with edge taps of every kind: a fractional Gaussian edge
#: (3 sigma_h / dt = 10.15), whole ones (3 x 0.0625 / dt = 13.5 -> 0.5), a
#: triangular of zero end taps (w / dt = 4), a boxcar with a partial tap.
WIDTHS = [0.047, 0.0625, 4 * DT, 0.045, 0.2]


def impulse_response(realisation, n):
    """v[k] for e = delta: d, then c T^(k-1) g."""
    T, g, c, d = realisation
    response, state = [d], g
    for _ in range(n - 1):
        response.append(c @ state)
        state = T @ state
    return np.array(response)


def acf(realisation, lags):
    """Autocorrelation of the realised noise from its impulse response (decayed by 2,000 steps)."""
    response = impulse_response(realisation, 2000 + lags)
    return [response[: len(response) - lag] @ response[lag:] for lag in range(lags)]


@pytest.mark.parametrize("width", WIDTHS)
@pytest.mark.parametrize("name", list(FAMILIES))
def test_realisation_is_the_shaping_filter(name, width):
    # The finite kernels' observable form reproduces their taps (zeros
    # trimmed: a shift, which leaves the noise's law unchanged); the
    # exponential family's AR(1) has the impulse response sqrt(1 - phi^2)
    # phi^k, of which the taps are the truncation. Either way the noise has
    # the family's autocorrelation, to 1e-12.
    family = FAMILIES[name]
    realisation = family.realisation(width, DT)
    taps = np.trim_zeros(family.taps(width, DT))
    response = impulse_response(realisation, len(taps) + 5)
    np.testing.assert_allclose(response[: len(taps)], taps, rtol=0, atol=1e-15)
    # the exponential's response goes on (the taps stop where its energy is 1e-16)
    assert np.abs(response[len(taps) :]).max(initial=0.0) < 1e-8
    np.testing.assert_allclose(
        acf(realisation, 12), family.autocorrelation(width, DT, 12), atol=1e-12
    )
    # Vectorised over widths: g and d per width (white noise: one for all),
    # T and c broadcast (the finite kernels share them, zero-padded).
    widths = np.array([width, 2 * width])
    T, g, c, d = family.realisation(widths, DT)
    for i, one in enumerate(widths):
        g_i, d_i = np.broadcast_to(g, (2, g.shape[-1]))[i], np.broadcast_to(d, 2)[i]
        draw = (T if T.ndim == 2 else T[i], g_i, c if c.ndim == 1 else c[i], d_i)
        np.testing.assert_allclose(acf(draw, 12), family.autocorrelation(one, DT, 12), atol=1e-12)


@pytest.mark.parametrize("sensor", ["ma1", "diagonal"])
def test_white_model_has_the_coloured_models_variance_per_step(sensor):
    # The baseline differs from the coloured model only in the noise's
    # memory: the variance that enters x per step is sigma_c^2 (+ the
    # diagonal term's sigma_n^2) in both, taken at the stationary register.
    kwargs = dict(sigma_c=0.01, sigma_n=0.005, dt=DT, sensor=sensor)
    white = channel_model("yaw", 0.72, [0.03, -0.03], family="white", width=1.0, **kwargs)
    coloured = channel_model("yaw", 0.72, [0.03, -0.03], family="gaussian", width=0.047, **kwargs)
    F, Q = coloured.transition, coloured.process_covariance
    stationary = scipy.linalg.solve_discrete_lyapunov(F[1:, 1:], Q[1:, 1:])
    entering = F[0, 1:] @ stationary @ F[0, 1:] + Q[0, 0]
    np.testing.assert_allclose(entering, white.process_covariance[0, 0], rtol=1e-12)
    np.testing.assert_allclose(white.process_covariance[0, 0], 1e-4 + 2.5e-5 * (sensor != "ma1"))
    assert white.sensor_variance == coloured.sensor_variance == 2.5e-5 * (sensor == "ma1")


@pytest.fixture(scope="module")
def run():
    return simulate_experiment(ROBOT, 110.0, 30.0, "v2", rng=3)


@pytest.fixture(scope="module")
def exported(run):
    theta = [110.0, 30.0, 0.047, 0.01, 0.005, 0.047, 0.005, 0.003]
    return export_prior(posterior_at([run], theta, channels=("yaw", "vx")), order=0)


def test_models_of_an_exported_prior_are_at_its_posterior_means(exported, run):
    assert check_prior(exported, run, robot=ROBOT) == ("yaw", "vx")
    models = filter_models(exported)
    assert list(models) == ["yaw", "vx"]
    parameters = exported["noise"]["parameters"]
    Ad, Bd = np.array(exported["model"]["Ad"]), np.array(exported["model"]["Bd"])
    for channel, i in (("yaw", 2), ("vx", 0)):
        mean = {
            name: parameters[f"{name}[{channel}]"]["mean"]
            for name in ("sigma_h", "sigma_c", "sigma_n")
        }
        reference = channel_model(
            channel, Ad[i, i], Bd[i], family="gaussian", width=mean["sigma_h"],
            sigma_c=mean["sigma_c"], sigma_n=mean["sigma_n"], dt=exported["dt"],
        )  # fmt: skip
        for field in dataclasses.fields(reference):
            np.testing.assert_array_equal(
                getattr(models[channel], field.name), getattr(reference, field.name)
            )
    white = filter_models(exported, noise="white", channels=["vx"])
    assert list(white) == ["vx"] and white["vx"].size == 1
    assert white["vx"].transition[0, 0] == Ad[0, 0]


def _without(prior, path):
    """A deep copy of the prior without the field at ``path`` ("a.b")."""
    copy = {key: dict(value) if isinstance(value, dict) else value for key, value in prior.items()}
    *parents, last = path.split(".")
    node = copy
    for key in parents:
        node = node[key]
    del node[last]
    return copy


def test_bad_priors_are_refused_naming_the_field_and_value(run):
    prior = truth_prior()
    other_rate = {**prior, "dt": 1 / 36}
    other_robot = {**prior, "robot": {"name": "husky"}}
    cases = [
        (lambda: check_prior(other_rate, run), "dt", "36 Hz"),
        (lambda: check_prior(other_robot, run), "robot", "'husky'"),
        (lambda: check_prior({**prior, "format": "dem/1"}, run), "format", "'dem/1'"),
        (lambda: check_prior(truth_prior(("yaw",)), run, ["vx"]), "channels", "'vx'"),
        (
            lambda: check_prior(prior, run, robot=dataclasses.replace(ROBOT, name="husky")),
            "robot.name",
            "'husky'",
        ),
        (lambda: filter_models(_without(prior, "model.Ad")), "model.Ad", "no field"),
        (lambda: filter_models(prior, noise="pink"), "noise", "'pink'"),
        (lambda: filter_models(prior, channels=["roll"]), "channels", "'roll'"),
    ]
    for call, field, value in cases:
        with pytest.raises(InputError, match=value) as error:
            call()
        assert error.value.field == field
    yaw_only = dataclasses.replace(run, vx=None, vy=None)
    with pytest.raises(DataError, match="'vx' is not in this experiment"):
        check_prior(prior, yaw_only)


def _edited(prior: dict, path: str, value) -> dict:
    """A deep copy of ``prior`` with the field at ``path`` ("a.b") set to ``value``."""
    copy = json.loads(json.dumps(prior))
    *parents, last = path.split(".")
    node = copy
    for key in parents:
        node = node[key]
    node[last] = value
    return copy


#: Fields of the wrong type the filters read: (path, value, words of the error).
WRONG_TYPES = [
    ("dt", "fast", "expected a positive number of seconds, got 'fast'"),
    ("dt", None, "expected a positive number of seconds, got None"),
    ("dt", 0, "expected a positive number of seconds, got 0"),
    ("dt", True, "expected a positive number of seconds, got True"),
    ("robot", [], "expected an object of named fields, got []"),
    ("robot.mass", "heavy", "expected a positive number, got 'heavy'"),
    ("robot.name", 7, "expected text, got 7"),
    (
        "noise.channels",
        "yaw",
        "expected a non-empty list of channel names (vx, vy, yaw), got 'yaw'",
    ),
    ("noise.channels", [], "expected a non-empty list of channel names (vx, vy, yaw), got []"),
    ("noise.channels", ["yaw", "yaw"], "a channel is listed twice"),
    ("noise.channels", ["roll"], "unknown channel 'roll'"),
    ("noise.family", ["white"], "unknown noise family ['white']"),
    ("noise.sensor", 1, "unknown sensor model 1"),
    ("noise.shared_width", "no", "expected true or false, got 'no'"),
    ("noise.pose_channels", None, "expected a list of channel names"),
    ("noise.parameters.sigma_c", 3, "expected an object with the mean, got 3"),
    ("damping.mean", [110.0], "expected ['d_lat', 'd_long'], got [110.0]"),
    ("damping.mean", ["a", "b"], "expected numbers"),
    ("model", 5, "expected an object of named fields, got 5"),
    ("draws", {"sigma_c": [0.01, 0.02], "sigma_n": [0.005]}, "different numbers of draws"),
    ("draws", {"sigma_c": "x"}, "expected numbers"),
    ("generalised_coordinates", {"order": "two"}, "expected a whole number >= 0, got 'two'"),
    ("generalised_coordinates", {"order": 1.5}, "expected a whole number >= 0, got 1.5"),
    ("sensor_noise", {"smoothness_seconds": "x"}, "expected a positive number of seconds"),
]


@pytest.mark.parametrize(
    ("path", "value", "words"), WRONG_TYPES, ids=[f"{p}={v!r}" for p, v, _ in WRONG_TYPES]
)
def test_a_field_of_the_wrong_type_is_refused_by_name(run, path, value, words):
    """Issue 24: "dt": "fast" was a ValueError, null a TypeError, 0 a ZeroDivisionError."""
    prior = _edited(truth_prior(("yaw",), family="white"), path, value)
    for call in (lambda: check_prior(prior, run), lambda: check_prior_fields(prior)):
        with pytest.raises(InputError) as error:
            call()
        assert words in str(error.value)
        assert error.value.field.startswith(path)
    with pytest.raises(DataError, match=rf"^bad\.json: {re.escape(error.value.field)}: "):
        check_prior_fields(prior, source="bad.json")


def test_a_prior_within_one_percent_of_the_rate_is_accepted(run):
    # The experiment's mean step may differ from the prior's by rounding or
    # resampling; within PRIOR_RATE_TOLERANCE (1 %) the prior applies, beyond it not.
    assert check_prior({**truth_prior(), "dt": DT * 1.009}, run) == ("yaw", "vx", "vy")
    with pytest.raises(InputError, match=r"70\.59 Hz"):
        check_prior({**truth_prior(), "dt": DT * 1.02}, run)
