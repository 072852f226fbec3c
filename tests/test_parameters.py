"""The parameter layout and the validation of prior overrides (bayes_jackal.model.parameters)."""

from __future__ import annotations

import numpy as np
import pytest

from bayes_jackal import InputError, load_profile
from bayes_jackal.io.simulate import Series, simulate_experiment
from bayes_jackal.likelihood.priors import Prior
from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood
from bayes_jackal.model.kernels import FAMILIES, Exponential
from bayes_jackal.model.parameters import SHARED_GROUP, ParameterLayout, prior_overrides

ROBOT = load_profile()


@pytest.fixture(scope="module")
def runs():
    """Two 10 s runs measuring every channel."""
    series = Series(0.3, np.deg2rad(22.5), 10.0)
    return [simulate_experiment(ROBOT, 110.0, 30.0, series, rng=k, name=f"r{k}") for k in (1, 2)]


@pytest.mark.parametrize(
    ("family", "sensor", "channels", "shared", "names", "labels"),
    [
        ("gaussian", "ma1", ("yaw",), True, ["sigma_h", "sigma_c", "sigma_n"], ["yaw"]),
        (
            "exponential",
            "ma1",
            ("yaw", "vx"),
            True,
            [f"{b}[{c}]" for c in ("yaw", "vx") for b in ("width", "sigma_c", "sigma_n")],
            ["yaw", "vx"],
        ),
        ("white", "diagonal", ("yaw",), False, ["sigma_c[r1]", "sigma_c[r2]"], ["r1", "r2"]),
        (
            "white",
            "ma1",
            ("yaw", "vy"),
            False,
            [
                f"{b}[{e}, {c}]"
                for e in ("r1", "r2")
                for c in ("yaw", "vy")
                for b in ("sigma_c", "sigma_n")
            ],
            ["r1, yaw", "r1, vy", "r2, yaw", "r2, vy"],
        ),
    ],
)
def test_the_layout_names_the_likelihood_parameters(
    runs, family, sensor, channels, shared, names, labels
):
    likelihood = ResidualLikelihood(
        runs, ROBOT, family=family, channels=channels, shared_noise=shared, sensor=sensor
    )
    layout = likelihood.layout
    assert layout.names == ("d_lat", "d_long", *names)
    assert likelihood.parameter_names == list(layout.names)
    assert list(layout.labels) == labels
    assert layout.bases == tuple(name.split("[")[0] for name in layout.names)
    # Each noise group's columns hold its parameters, in noise_bases order.
    for group, label in enumerate(labels):
        suffix = "" if len(labels) == 1 else f"[{label}]"
        columns = layout.noise_columns(group)
        assert [layout.names[j] for j in columns] == [f"{b}{suffix}" for b in layout.noise_bases]
        assert {layout.column_groups[j] for j in columns} == {group}


def test_groups_are_keyed_by_channel_and_experiment_or_shared():
    pooled = ParameterLayout("gaussian", "ma1", ("yaw", "vx"), ("r1", "r2"), True)
    assert pooled.groups == (("yaw", SHARED_GROUP), ("vx", SHARED_GROUP))
    assert pooled.group("vx", "r2") == pooled.group("vx", "anything") == 1
    separate = ParameterLayout("gaussian", "ma1", ("yaw", "vx"), ("r1", "r2"), False)
    assert separate.group("vx", "r2") == 3
    with pytest.raises(InputError, match=r"no noise group \('vy', 'r1'\)"):
        separate.group("vy", "r1")
    with pytest.raises(InputError, match="no parameter 'width'"):
        separate.column("width", 0)  # the Gaussian's width is sigma_h


@pytest.mark.parametrize(
    ("shared_noise", "labels"),
    [(True, ["yaw", "vx"]), (False, ["r1, yaw", "r1, vx", "r2, yaw", "r2, vx"])],
)
def test_one_width_is_one_column_that_every_group_reads(shared_noise, labels):
    # One width (column 2, no suffix), then each group's sigma_c, sigma_n:
    # group g's are columns 3 + 2 g and 4 + 2 g.
    layout = ParameterLayout(
        "gaussian", "ma1", ("yaw", "vx"), ("r1", "r2"), shared_noise, shared_width=True
    )
    groups = len(labels)
    assert layout.names == (
        "d_lat",
        "d_long",
        "sigma_h",
        *(f"{b}[{label}]" for label in labels for b in ("sigma_c", "sigma_n")),
    )
    assert layout.bases == tuple(name.split("[")[0] for name in layout.names)
    assert layout.names_of("sigma_h") == ("sigma_h",)
    assert layout.column_groups == (None, None, None, *np.repeat(range(groups), 2))
    assert len(layout.bases) == len(layout.names) == 3 + 2 * groups
    theta = np.arange(3.0 + 2 * groups)[None] + 100.0 * np.arange(2.0)[:, None]
    for g in range(groups):
        assert layout.noise_columns(g) == [2, 3 + 2 * g, 4 + 2 * g]
        assert layout.column("sigma_h", g) == layout.column("sigma_h") == 2
        width, sigma_c, sigma_n = layout.noise_parameters(theta, g)
        np.testing.assert_array_equal(
            np.stack([width, sigma_c, sigma_n]), theta[:, [2, 3 + 2 * g, 4 + 2 * g]].T
        )
    # The default is a width per group; white noise has none to share.
    assert ParameterLayout("gaussian", "ma1", ("yaw",), ("r1",), True).shared_width is False
    white = {
        ParameterLayout("white", "ma1", ("yaw", "vx"), ("r1",), True, shared_width=one).names
        for one in (True, False)
    }
    assert len(white) == 1


def test_noise_parameters_read_the_group_columns():
    layout = ParameterLayout("triangular", "ma1", ("yaw", "vx"), ("r1",), True)
    theta = np.arange(8.0)[None] + 10.0 * np.arange(2.0)[:, None]  # two parameter vectors
    width, sigma_c, sigma_n = layout.noise_parameters(theta, 1)
    np.testing.assert_array_equal(np.stack([width, sigma_c, sigma_n]), theta[:, 5:8].T)
    white = ParameterLayout("white", "diagonal", ("yaw",), ("r1",), True)
    width, sigma_c, sigma_n = white.noise_parameters(np.array([[1.0, 2.0, 0.3]]), 0)
    assert (width[0], sigma_c[0], sigma_n[0]) == (1.0, 0.3, 0.0)  # unit width, one sd


def test_an_unknown_prior_key_is_refused_naming_the_keys_allowed():
    allowed = (
        "['d_lat', 'd_long', 'sigma_h', 'sigma_c', 'sigma_n', 'sigma_p', 'speed_ratio', 'width']"
    )
    with pytest.raises(InputError) as caught:
        prior_overrides({"d_latt": (10.0, 500.0)})
    assert str(caught.value).startswith(
        f"prior_overrides: unknown prior 'd_latt'; use one of {allowed}"
    )
    with pytest.raises(InputError, match="--prior: unknown prior 'mass'"):
        prior_overrides({"mass": (1, 2)}, field="--prior")


@pytest.mark.parametrize(
    ("overrides", "pattern"),
    [
        ({"width": (0.1, 0.2), "sigma_h": (0.1, 0.2)}, "the same prior"),
        ({"sigma_c": ("low", 1)}, r"priors\.sigma_c: low and high must be numbers"),
        ({"sigma_c": (1.0,)}, "must be numbers"),
        ({"d_lat": (500, 100)}, r"priors\.d_lat: .*got \[500\.0, 100\.0\]"),
        ({"sigma_n": (0.0, 1.0)}, r"priors\.sigma_n: .*0 < low < high"),
        # 1e400 reads as inf: said so, not as a range that "excludes every value".
        ({"d_lat": ("1", "1e400")}, r"\['1', '1e400'\]: read as \[1\.0, inf\]"),
    ],
)
def test_bad_prior_overrides_are_refused(overrides, pattern):
    with pytest.raises(InputError, match=pattern):
        prior_overrides(overrides)


@pytest.mark.parametrize("family", ["gaussian", "exponential", "moving-average"])
@pytest.mark.parametrize("key", ["width", "sigma_h"])
def test_width_and_sigma_h_both_set_every_family_width(runs, family, key):
    likelihood = ResidualLikelihood(runs, ROBOT, family=family, channels=("yaw",))
    prior = Prior.for_likelihood(likelihood, ROBOT, {key: (0.01, 0.2), "d_lat": (50, 500)})
    layout = likelihood.layout
    width = layout.column(layout.width_name, 0)
    assert (prior.low[width], prior.high[width]) == (0.01, 0.2)
    assert (prior.low[0], prior.high[0]) == (50.0, 500.0)
    unchanged = layout.column("sigma_c", 0)
    assert (prior.low[unchanged], prior.high[unchanged]) == ROBOT.priors["sigma_c"]


def test_the_library_refuses_a_misspelt_override(runs):
    likelihood = ResidualLikelihood(runs, ROBOT, family="white", channels=("yaw",))
    with pytest.raises(InputError, match="unknown prior 'sigma_hh'"):
        Prior.for_likelihood(likelihood, ROBOT, {"sigma_hh": (0.01, 0.2)})
    # A width range is valid for white noise too (unused), so one set of
    # overrides serves every family of a comparison.
    prior = Prior.for_likelihood(likelihood, ROBOT, {"width": (0.01, 0.2)})
    assert prior.names == ("d_lat", "d_long", "sigma_c", "sigma_n")


class Lowpass(Exponential):
    """A family defined here only, whose width has a name of its own: ``tau``."""

    name = "lowpass"
    width_name = "tau"


def test_a_registered_family_s_own_width_name_is_a_width_key(runs, monkeypatch):
    # Unknown until registered, then one more name of the one width prior
    # (docs/families.md): it sets the width of every family, its own included.
    with pytest.raises(InputError, match="unknown prior 'tau'"):
        prior_overrides({"tau": (0.01, 0.2)})
    monkeypatch.setitem(FAMILIES, "lowpass", Lowpass())
    assert prior_overrides({"tau": (0.01, 0.2)}) == {"sigma_h": (0.01, 0.2)}
    for family in ("lowpass", "gaussian"):
        likelihood = ResidualLikelihood(runs, ROBOT, family=family, channels=("yaw",))
        prior = Prior.for_likelihood(likelihood, ROBOT, {"tau": (0.01, 0.2)})
        width = likelihood.layout.column(likelihood.layout.width_name, 0)
        assert (prior.names[width], prior.low[width], prior.high[width]) == (
            "tau" if family == "lowpass" else "sigma_h",
            0.01,
            0.2,
        )
    for other in ("width", "sigma_h"):
        with pytest.raises(InputError, match=f"{other} and tau are the same prior"):
            prior_overrides({other: (0.01, 0.2), "tau": (0.01, 0.3)})
    allowed = (
        "['d_lat', 'd_long', 'sigma_h', 'sigma_c', 'sigma_n', 'sigma_p', 'speed_ratio', "
        "'width', 'tau']"
    )
    with pytest.raises(InputError) as caught:
        prior_overrides({"taus": (0.01, 0.2)})
    assert str(caught.value) == (
        f"prior_overrides: unknown prior 'taus'; use one of {allowed} "
        "(width and tau are sigma_h: every family's width)"
    )
