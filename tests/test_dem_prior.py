"""The exported prior as a typed value: ActiveInferencePrior, its JSON and the file (issue 26)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from synthetic_posteriors import posterior_at

import bayes_jackal as bj
from bayes_jackal import DataError, InputError
from bayes_jackal.dem import (
    PRIOR_FORMAT,
    ActiveInferencePrior,
    export_prior,
    read_prior,
    write_prior,
)
from bayes_jackal.filters import estimate_states, filter_models, kalman_filter
from bayes_jackal.io.simulate import simulate_experiment

ROBOT = bj.load_profile()
#: The top-level keys of an exported prior.json, in the file's order (docs/guide/prior.md).
FILE_KEYS = [
    "format", "bayes_jackal_version", "source", "converged", "experiments", "robot", "dt",
    "states", "inputs", "model", "damping", "noise", "generalised_coordinates", "draws",
    "sensor_noise", "smoothness", "log_precision", "operating_point",
]  # fmt: skip


@pytest.fixture(scope="module")
def run():
    return simulate_experiment(ROBOT, 110.0, 30.0, "v2", rng=3)


@pytest.fixture(scope="module")
def exported(run):
    """Gaussian noise on yaw and vx (order 2); white noise of one total sd (order 0)."""
    gaussian = posterior_at(
        [run], [110.0, 30.0, 0.047, 0.01, 0.005, 0.047, 0.005, 0.003], channels=("yaw", "vx")
    )
    white = posterior_at([run], [110.0, 30.0, 0.01], family="white", sensor="diagonal")
    return {
        "gaussian": export_prior(gaussian, order=2, source="gaussian.nc"),
        "white": export_prior(white, order=0),
    }


def minimal():
    """A prior built by hand: the fields every prior holds, and no other."""
    return {
        "format": PRIOR_FORMAT,
        "robot": {"name": ROBOT.name},
        "dt": ROBOT.dt,
        "model": {},
        "damping": {"mean": [110.0, 30.0]},
        "noise": {
            "family": "white",
            "channels": ["yaw"],
            "parameters": {"sigma_c": {"mean": 0.01}, "sigma_n": {"mean": 0.005}},
        },
    }


@pytest.mark.parametrize("name", ["gaussian", "white"])
def test_the_file_is_the_json_of_the_prior_byte_for_byte(exported, name, tmp_path):
    prior = exported[name]
    assert isinstance(prior, ActiveInferencePrior)
    path = write_prior(prior, tmp_path / "prior.json")
    # The dict path: the same JSON written as a plain dict, as export_prior returned it
    # before the class (write_json at indent 1 of the dict).
    as_dict = write_prior(prior.to_json(), tmp_path / "dict.json")
    assert path.read_bytes() == as_dict.read_bytes()
    assert path.read_text() == json.dumps(prior.to_json(), indent=1, allow_nan=False)
    stored = json.loads(path.read_text())
    assert list(stored) == FILE_KEYS and stored == prior.to_json()
    # Read and written again, the file is unchanged.
    again = read_prior(path)
    assert again == prior and isinstance(again, ActiveInferencePrior)
    assert write_prior(again, tmp_path / "again.json").read_bytes() == path.read_bytes()


def test_a_white_prior_of_one_total_sd_keeps_its_nulls(exported, tmp_path):
    prior = exported["white"]
    assert prior.sensor_noise is None and prior.source is None
    assert "sensor_noise" in prior and prior["sensor_noise"] is None and not prior.absent
    stored = json.loads(write_prior(prior, tmp_path / "prior.json").read_text())
    assert stored["sensor_noise"] is None and stored["source"] is None


@pytest.mark.parametrize("name", ["gaussian", "white"])
def test_from_json_of_to_json_is_the_prior(exported, name):
    prior = exported[name]
    again = ActiveInferencePrior.from_json(prior.to_json())
    assert again == prior and again.to_json() == prior.to_json()
    for field in dataclasses.fields(ActiveInferencePrior):
        assert getattr(again, field.name) == getattr(prior, field.name), field.name
    assert ActiveInferencePrior.from_json(prior) is prior  # a prior is returned as it is
    assert (prior.family, prior.channels, prior.order) == (
        prior.noise["family"],
        tuple(prior.noise["channels"]),
        prior.generalised_coordinates["order"],
    )


def test_to_json_is_a_copy_and_the_prior_is_frozen(exported):
    prior = exported["gaussian"]
    edited = prior.to_json()
    edited["noise"]["family"] = "white"
    edited["model"]["Ad"][0][0] = 2.0
    assert prior.noise["family"] == "gaussian" and prior.model["Ad"][0][0] < 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        prior.dt = 0.01
    with pytest.raises(TypeError):
        prior["dt"] = 0.01
    # from_json copies the mapping too: editing it later leaves the prior alone.
    mapping = minimal()
    made = ActiveInferencePrior.from_json(mapping)
    mapping["noise"]["channels"].append("vx")
    assert made.channels == ("yaw",)


@pytest.mark.parametrize("name", ["gaussian", "white"])
def test_the_mapping_is_the_json(exported, name):
    prior = exported[name]
    json_form = prior.to_json()
    assert dict(prior) == json_form and list(prior) == list(json_form) == FILE_KEYS
    assert len(prior) == len(json_form)
    for key in FILE_KEYS:
        assert prior[key] == json_form[key] and prior[key] is getattr(prior, key)
    assert prior.get("absent") is None and "extra" not in prior
    # As a dict's |: the JSON with keys replaced, a dict the caller may edit.
    merged = prior | {"dt": 0.01}
    assert type(merged) is dict and merged == {**json_form, "dt": 0.01} and prior.dt != 0.01
    assert {"dt": 0.01} | prior == json_form
    with pytest.raises(KeyError):
        prior["A"]


def test_a_prior_built_by_hand_keeps_what_it_holds(tmp_path):
    hand = minimal() | {"notes": "edited by hand", "sensor_noise": None}
    prior = ActiveInferencePrior.from_json(hand)
    assert prior.to_json() == hand and prior == hand
    # In the file's order, then the keys this version does not know.
    order = ["format", "robot", "dt", "model", "damping", "noise", "sensor_noise", "notes"]
    assert list(prior) == list(prior.to_json()) == order
    assert prior.extra == {"notes": "edited by hand"} and prior.sensor_noise is None
    assert prior.absent == set(FILE_KEYS) - set(hand)
    assert "draws" not in prior and prior.draws is None and prior.order is None
    path = write_prior(hand, tmp_path / "hand.json")  # a mapping of the format: checked, written
    assert json.loads(path.read_text()) == hand and read_prior(path) == prior


#: Malformed priors: (edit of the minimal prior, the field named, words of the error).
MALFORMED = [
    (lambda p: p.pop("damping"), "damping.mean", "the prior has no field 'damping.mean'"),
    (lambda p: p.update(format="bayes_jackal.noise_prior/1"), "format", "not a prior"),
    (lambda p: p.update(dt="fast"), "dt", "expected a positive number of seconds, got 'fast'"),
    (lambda p: p["noise"].update(family="pink"), "noise.family", "unknown noise family 'pink'"),
    (lambda p: p["model"].update(Ad=[1.0]), "model.Ad", "expected a finite 3 x 3 matrix"),
    (lambda p: p.update(draws={"sigma_c": [0.01, -1.0]}), "draws.sigma_c", "positive numbers"),
]


@pytest.mark.parametrize(
    ("edit", "field", "words"), MALFORMED, ids=[field for _, field, _ in MALFORMED]
)
def test_malformed_json_is_refused_naming_the_field(edit, field, words, tmp_path):
    mapping = minimal()
    edit(mapping)
    with pytest.raises(InputError, match=f"^{field}: ") as error:
        ActiveInferencePrior.from_json(mapping)
    assert error.value.field == field and words in str(error.value)
    with pytest.raises(DataError, match=rf"^bad\.json: {field}: ") as error:
        ActiveInferencePrior.from_json(mapping, source="bad.json")
    assert error.value.field == field and words in str(error.value)
    if field != "format":  # a mapping of another format is written as it is (below)
        with pytest.raises(InputError, match=f"^{field}: "):
            write_prior(mapping, tmp_path / "prior.json")
        assert not (tmp_path / "prior.json").exists()


def test_a_prior_made_directly_is_checked():
    fields = {key: value for key, value in minimal().items() if key != "format"}
    assert ActiveInferencePrior(**fields).to_json()["sensor_noise"] is None  # null, not absent
    cases = [
        ({**fields, "dt": -1 / 72}, "dt", "-72 Hz"),
        ({**fields, "absent": {"dt"}}, "absent", "every prior holds it"),
        ({**fields, "absent": {"draws"}, "draws": {"count": 0}}, "absent", "it holds a value"),
        ({**fields, "absent": {"A"}}, "absent", "'A' is no field"),
        ({**fields, "extra": {"noise": {}}}, "extra", "'noise' is a field"),
        ({**fields, "extra": {1: {}}}, "extra", "1 is no text"),
    ]
    for given, field, words in cases:
        with pytest.raises(InputError, match=words) as error:
            ActiveInferencePrior(**given)
        assert error.value.field == field


def test_a_json_array_is_no_prior():
    with pytest.raises(DataError, match=r"^prior\.json: format: not a prior this version reads"):
        ActiveInferencePrior.from_json([1, 2], source="prior.json")


def test_another_format_is_written_as_it_is(tmp_path):
    noise_prior = {"format": "bayes_jackal.noise_prior/1", "family": "gaussian", "dt": 0.01}
    path = write_prior(noise_prior, tmp_path / "gyro.prior.json")
    assert json.loads(path.read_text()) == noise_prior


def test_the_filters_take_a_prior_and_its_json_alike(exported, run):
    prior = exported["gaussian"]
    for parameters in ("plug-in", "averaged"):
        from_prior = filter_models(prior, parameters=parameters)
        from_json = filter_models(prior.to_json(), parameters=parameters)
        for channel, model in from_prior.items():
            for field in dataclasses.fields(model):
                np.testing.assert_array_equal(
                    getattr(model, field.name), getattr(from_json[channel], field.name)
                )
    estimate = kalman_filter(run, prior, channels=["yaw"])["yaw"]
    again = kalman_filter(run, prior.to_json(), channels=["yaw"])["yaw"]
    np.testing.assert_array_equal(estimate.mean, again.mean)
    options = {"filters": ["generalised"], "channels": ["yaw"]}
    [(_, from_prior)] = estimate_states(run, prior, **options)["generalised"].items()
    [(_, from_json)] = estimate_states(run, prior.to_json(), **options)["generalised"].items()
    np.testing.assert_array_equal(from_prior.mean, from_json.mean)
