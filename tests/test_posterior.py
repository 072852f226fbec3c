"""The posterior file: round trip, typed metadata, old files, refused files (docs/design.md §7)."""

from __future__ import annotations

import copy
import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from bayes_jackal import DataError, InputError, load_experiments, load_profile
from bayes_jackal._runtime.arviz_quiet import az
from bayes_jackal._runtime.defaults import CHANNELS
from bayes_jackal.io.experiment import write_netcdf
from bayes_jackal.io.simulate import Series, simulate_experiment
from bayes_jackal.likelihood import LogPosterior
from bayes_jackal.likelihood.priors import Prior
from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood
from bayes_jackal.posterior import Posterior
from bayes_jackal.posterior.file_format import (
    FORMAT,
    ROBOT_CONSTANTS,
    experiment_arrays,
    store_comparison,
    store_criticism,
)
from bayes_jackal.posterior.posterior import (
    build_inference_data,
    load_posterior,
    save_posterior,
)
from bayes_jackal.posterior.records import Convergence, Evidence
from bayes_jackal.posterior.summary import summarize

ROBOT = load_profile()
#: A posterior written by bayes_jackal 0.1.0 before the format had an owner,
#: and what that version's summarize said of it (tests/data/README.md).
OLD_FILE = Path(__file__).parent / "data" / "posterior_format1_v0.nc"
OLD_SUMMARY = {
    ("d_lat", "mean"): 36.408558802366834,
    ("sigma_c", "sd"): 0.00015590805711891196,
    ("ratio", "hdi_97%"): 3.6803520895780584,
}
#: Diagnostics as the sampler writes them (bayes_jackal.inference.sampling), every field set.
WALKERS, DRAWS = 8, 6


@pytest.fixture(scope="module")
def sampled():
    """(likelihood, prior, chain, diagnostics, posterior): two 10 s runs, noise per run."""
    runs = [
        simulate_experiment(ROBOT, 110.0, 30.0, Series(0.3, np.deg2rad(22.5), 10.0), rng=k, name=n)
        for k, n in ((4, "v1_01"), (5, "v1_02"))
    ]
    likelihood = ResidualLikelihood(
        runs, ROBOT, family="exponential", channels=("yaw", "vx"), shared_noise=False
    )
    prior = Prior.for_likelihood(likelihood, ROBOT, {"width": (0.002, 0.5)})
    rng = np.random.default_rng(3)
    theta = [110.0, 30.0, *[0.05, 0.01, 0.005] * len(likelihood.layout.groups)]
    chain = np.log(theta) + 0.02 * rng.normal(size=(DRAWS, WALKERS, len(theta)))
    names = prior.names
    diagnostics = {
        "converged": False,
        "n_steps": 400,
        "walkers": WALKERS,
        "discard": 200,
        "thin": 33,
        "autocorr_time": dict.fromkeys(names, 66.0),
        "ess_autocorr": dict.fromkeys(names, 24.2),
        "acceptance_fraction": 0.31,
        "seed": 7,
        "settings": {"max_steps": 400, "autocorr_multiple": 50.0},
    }
    lp = rng.normal(size=(DRAWS, WALKERS))
    idata = build_inference_data(likelihood, prior, chain, lp, diagnostics)
    return likelihood, prior, chain, diagnostics, idata


def test_the_typed_metadata_are_what_was_sampled(sampled):
    likelihood, prior, _, diagnostics, idata = sampled
    metadata = Posterior.of(idata).metadata
    assert metadata.format == FORMAT
    assert metadata.layout == likelihood.layout
    assert metadata.layout.groups == (
        ("yaw", "v1_01"),
        ("vx", "v1_01"),
        ("yaw", "v1_02"),
        ("vx", "v1_02"),
    )
    assert metadata.engine == "fast" and metadata.steady is False
    assert metadata.prior.names == prior.names
    np.testing.assert_array_equal(metadata.prior.low, prior.low)
    np.testing.assert_array_equal(metadata.prior.high, prior.high)
    np.testing.assert_array_equal(metadata.prior.log_uniform, prior.log_uniform)
    # The "width" override is the exponential width's range.
    assert metadata.prior.low[likelihood.layout.column("width", 3)] == 0.002
    assert metadata.robot == ROBOT
    assert [e.name for e in metadata.experiments] == ["v1_01", "v1_02"]
    for record, run in zip(metadata.experiments, likelihood.experiments, strict=True):
        assert record.dt == run.dt and record.steady_window == run.steady_window
        assert record.truth == run.truth and record.series == run.series
        assert record.provenance == run.provenance and record.source == run.source
    assert metadata.convergence == Convergence(**diagnostics)
    assert metadata.truth == likelihood.experiments[0].truth
    assert metadata.evidence is None and metadata.criticism is None
    assert metadata.convergence_messages == () and metadata.task is None


def test_the_metadata_say_which_channels_each_experiment_measured(sampled):
    likelihood, prior, chain, diagnostics, idata = sampled
    # The simulated runs measure every channel; a second posterior of one of
    # them without vy (vx and yaw used) measures vx and yaw only.
    assert [e.channels for e in Posterior.of(idata).metadata.experiments] == [CHANNELS] * 2
    assert Posterior.of(idata).metadata.measured_channels == CHANNELS
    run, other = likelihood.experiments
    runs = [run, dataclasses.replace(other, vy=None)]
    partial = ResidualLikelihood(
        runs, ROBOT, family="exponential", channels=("yaw", "vx"), shared_noise=False
    )
    stored = build_inference_data(partial, prior, chain, chain[..., 0], diagnostics)
    metadata = Posterior.of(stored).metadata
    assert [e.channels for e in metadata.experiments] == [CHANNELS, ("vx", "yaw")]
    assert metadata.measured_channels == ("vx", "yaw")
    arrays = experiment_arrays(stored, 1)
    assert sorted(arrays) == ["omega_l", "omega_r", "t", "vx", "yaw_rate"]
    for field, values in arrays.items():
        np.testing.assert_array_equal(values, getattr(other, field))


def test_parameter_draws_follow_the_layout(sampled):
    likelihood, _, chain, _, idata = sampled
    draws, _ = Posterior.of(idata).draws()
    np.testing.assert_array_equal(draws, np.exp(chain))
    layout = likelihood.layout
    column = layout.column("sigma_c", layout.group("vx", "v1_02"))
    assert layout.names[column] == "sigma_c[v1_02, vx]"
    stored = idata.posterior["sigma_c"].sel(noise_group="v1_02, vx").transpose("draw", "chain")
    np.testing.assert_array_equal(draws[..., column], stored.values)


def test_a_saved_posterior_loads_with_the_same_metadata(sampled, tmp_path):
    chain, idata = sampled[2], copy.deepcopy(sampled[-1])
    store_comparison(
        idata,
        evidence=Evidence(-12.5, 0.03, "bridge"),
        nested=None,
        messages=["NOT CONVERGED: 400 steps"],
        task={"family": "exponential"},
    )
    store_criticism(idata, {"warnings": [], "criticism": {"damping_scale": {}}})
    loaded = load_posterior(save_posterior(idata, tmp_path / "p.nc"))
    before, after = Posterior.of(idata).metadata, Posterior.of(loaded).metadata
    for field in dataclasses.fields(before):
        if field.name != "prior":
            assert getattr(after, field.name) == getattr(before, field.name), field.name
    assert after.evidence == Evidence(-12.5, 0.03, "bridge") and after.evidence_nested is None
    assert after.convergence_messages == ("NOT CONVERGED: 400 steps",)
    assert after.task == {"family": "exponential"}
    np.testing.assert_array_equal(Posterior.of(loaded).draws()[0], np.exp(chain))
    assert [e.name for e in Posterior.of(loaded).experiments] == ["v1_01", "v1_02"]


def test_a_speed_damping_posterior_keeps_its_speed_ratios(tmp_path):
    # The speed model's ratios are parameters like the damping: stored,
    # summarised, and read back in the layout's order.
    import lab_simulator as lab  # the tests' DRIVE-like table, with steps at several speeds

    run = lab.write_drive_run(tmp_path / "drive.csv", n_steps=6, rng=3)
    with pytest.warns(UserWarning):  # the held encoders, said and replaced
        experiments = load_experiments([run.path], robot="husky", columns=lab.DRIVE_ALL_ROLES)
    husky = load_profile("husky")
    likelihood = ResidualLikelihood(
        experiments, husky, channels=("yaw",), family="white", damping="speed"
    )
    prior = Prior.for_likelihood(likelihood, husky)
    centre = np.log([306.5, 83.6, 1.5, 1.2, 0.05, 0.01])
    chain = centre + 0.01 * np.random.default_rng(1).normal(size=(12, 12, 6))
    lp = LogPosterior(likelihood, prior)(chain.reshape(-1, 6)).reshape(12, 12)
    diagnostics = {"converged": False, "n_steps": 12, "autocorr_time": {}, "ess_autocorr": {}}
    idata = build_inference_data(likelihood, prior, chain, lp, diagnostics)
    loaded = load_posterior(save_posterior(idata, tmp_path / "p.nc"))
    assert loaded.layout.names[2:4] == ("speed_ratio_lat", "speed_ratio_long")
    np.testing.assert_array_equal(loaded.draws()[0], np.exp(chain))
    # 144 draws of sd 0.01 in log around log 1.2: the mean within 1 % is ~10 of its sds.
    assert summarize(loaded)["speed_ratio_long"]["mean"] == pytest.approx(1.2, rel=0.01)


def test_a_file_written_before_the_format_had_an_owner_loads_and_summarises():
    idata = load_posterior(OLD_FILE)
    metadata = Posterior.of(idata).metadata
    assert metadata.format == "bayes_jackal.posterior/1"
    assert metadata.layout.names == ("d_lat", "d_long", "sigma_c", "sigma_n")
    assert metadata.layout.groups == (("yaw", "all"),)
    assert metadata.layout.shared_width is False  # no attribute: a width per group
    assert [e.name for e in metadata.experiments] == ["v2_01"]
    # Old files keep the body constants only: the rest is the installed profile's.
    assert {key: getattr(metadata.robot, key) for key in ROBOT_CONSTANTS if key != "source"} == {
        key: getattr(ROBOT, key) for key in ROBOT_CONSTANTS if key != "source"
    }
    assert metadata.robot.priors == ROBOT.priors
    assert metadata.convergence.n_steps == 200 and metadata.convergence.walkers == 8
    # Sampled when the damping's prior was uniform: read back as it was.
    assert metadata.prior.log_uniform.tolist() == [False, False, True, True]
    summary = summarize(idata)
    assert summary["family"] == "white" and summary["channels"] == ["yaw"]
    assert summary["n_steps"] == 200 and summary["converged"] is False
    for (name, key), value in OLD_SUMMARY.items():
        assert summary[name][key] == pytest.approx(value, rel=1e-12, abs=0), (name, key)
    assert summary["corr_d_lat_d_long"] == pytest.approx(0.6383411792858013, rel=1e-12)
    kinds = {"damping-scale-not-identified", "predictive-acf", "prior-boundary"}
    assert len(summary["warnings"]) == 8 and {w["kind"] for w in summary["warnings"]} == kinds
    draws, _ = Posterior.of(idata).draws()
    assert draws.shape[-1] == 4


def test_a_netcdf_that_is_not_a_posterior_is_refused(tmp_path):
    run = simulate_experiment(ROBOT, 110.0, 30.0, Series(0.3, 0.4, 10.0), rng=1)
    path = write_netcdf(run, tmp_path / "run.nc")
    with pytest.raises(DataError, match=rf"{re.escape(str(path))}: .*not a bayes_jackal poster"):
        load_posterior(path)
    plain = tmp_path / "plain.nc"
    xr.Dataset({"x": ("n", [1.0, 2.0])}).to_netcdf(plain, engine="h5netcdf")
    with pytest.raises(DataError, match=rf"{re.escape(str(plain))}: .*not a bayes_jackal poster"):
        load_posterior(plain)


def test_a_posterior_of_an_unknown_format_is_refused_naming_it(sampled, tmp_path):
    idata = copy.deepcopy(sampled[-1])
    idata.posterior.attrs = dict(idata.posterior.attrs) | {"format": "bayes_jackal.posterior/9"}
    path = save_posterior(idata, tmp_path / "future.nc")
    pattern = (
        rf"{re.escape(str(path))}: format: posterior format 'bayes_jackal.posterior/9' is "
        r"not one this version .* reads: \['bayes_jackal.posterior/1'\]"
    )
    with pytest.raises(DataError, match=pattern):
        load_posterior(path)


def test_a_posterior_with_a_nan_draw_is_refused_naming_the_file_and_the_draw(sampled, tmp_path):
    # export-prior and report said "d_lat: damping must be positive and finite,
    # got nan N s/m", naming neither the file nor the draw (issue 37, item 13).
    idata = copy.deepcopy(sampled[-1])
    idata.posterior["d_long"][1, 5] = np.nan
    path = save_posterior(idata, tmp_path / "damaged.nc")
    pattern = rf"{re.escape(str(path))}: posterior\.d_long: the draw at chain 1, draw 5 is nan"
    with pytest.raises(DataError, match=pattern):
        load_posterior(path)


@pytest.mark.parametrize(
    ("attribute", "value", "pattern"),
    [
        ("prior", None, r"prior: missing attribute"),
        ("experiments", "[{'name': 1", r"experiments: not a JSON text"),
        ("parameter_names", '["d_lat"]', r"parameter_names: parameter names \['d_lat'\] do not"),
    ],
)
def test_a_posterior_with_broken_attributes_is_refused_naming_the_attribute(
    sampled, tmp_path, attribute, value, pattern
):
    idata = copy.deepcopy(sampled[-1])
    attrs = dict(idata.posterior.attrs)
    attrs.pop(attribute)
    idata.posterior.attrs = attrs if value is None else attrs | {attribute: value}
    path = save_posterior(idata, tmp_path / "broken.nc")
    with pytest.raises(DataError, match=rf"{re.escape(str(path))}: {pattern}"):
        load_posterior(path)
    with pytest.raises(DataError, match=pattern):
        _ = Posterior.of(idata).metadata


def test_a_posterior_of_pose_channels_keeps_their_noise_and_poses(tmp_path):
    # vx, vy recorded as motion-capture poses: sigma_p is indexed by the pose
    # channels alone, sigma_n by yaw alone, and the file rebuilds the poses.
    from bayes_jackal import sample
    from bayes_jackal.io.bag_writer import write_bag
    from bayes_jackal.io.bags import read_bag
    from bayes_jackal.posterior.file_format import observed_residuals
    from bayes_jackal.posterior.posterior import model_autocovariance

    run = simulate_experiment(ROBOT, 110.0, 30.0, Series(0.3, 0.39, 10.0), rng=1, name="short")
    experiment = read_bag(write_bag(run, tmp_path / "short.bag", ROBOT, "ros1", rng=1), ROBOT)
    with pytest.warns(UserWarning, match="NOT CONVERGED"):  # kept short on purpose
        posterior = sample([experiment], family="white", max_steps=100, seed=1)
    assert posterior.posterior["sigma_p"].dims[-1] == "sigma_p_group"
    assert list(posterior.posterior["sigma_p_group"].values) == ["vx", "vy"]
    assert list(posterior.posterior["sigma_n_group"].values) == ["yaw"]
    back = load_posterior(save_posterior(posterior, tmp_path / "short.nc"))
    draws, _ = Posterior.of(back).draws()
    original, _ = Posterior.of(posterior).draws()
    np.testing.assert_array_equal(draws, original)
    metadata = Posterior.of(back).metadata
    assert metadata.layout.pose_channels == ("vx", "vy")
    assert metadata.experiments[0].pose_samples == 5
    summary = summarize(back)
    assert {"sigma_p[vx]", "sigma_p[vy]", "sigma_n[yaw]"} <= set(summary)
    residuals = {c: observed_residuals(back, 0, c) for c in ("yaw", "vx")}
    assert np.isfinite(residuals["vx"]).all()
    assert len(residuals["vx"]) == len(residuals["yaw"]) - 1  # two increments each
    [rebuilt] = Posterior.of(back).experiments
    np.testing.assert_array_equal(rebuilt.pose.x, experiment.pose.x)
    acov = model_autocovariance(metadata, 0, "vx", draws[0], 4)
    assert acov.shape == (draws.shape[1], 4) and np.all(acov[:, 3] == 0)  # white + MA(2)


def test_a_posterior_reads_its_metadata_once_and_again_after_a_stored_result(sampled):
    *_, idata = sampled
    posterior = Posterior.of(copy.deepcopy(idata))
    assert Posterior.of(posterior) is posterior  # a Posterior is taken as it is
    first = posterior.metadata
    assert posterior.metadata is first  # read once, not per call
    store_criticism(posterior, {"warnings": [], "criticism": {"damping_scale": {}}})
    # A result stored later changes the attributes: they are read again.
    assert posterior.metadata is not first
    assert posterior.metadata.criticism == {"warnings": [], "criticism": {"damping_scale": {}}}
    assert first.criticism is None


def test_a_copy_or_slice_of_a_posterior_reads_its_groups_anew(sampled):
    *_, idata = sampled
    posterior = Posterior.of(copy.deepcopy(idata))
    n = len(posterior.experiments[0].t)
    # arviz's isel deep-copies: what the copy reads must be its own groups.
    sliced = posterior.isel(groups="constant_data", time_0=slice(0, 50))
    assert isinstance(sliced, Posterior) and len(sliced.experiments[0].t) == 50
    assert len(posterior.experiments[0].t) == n
    # A pickle (a worker's result) carries the groups, not what was read from them.
    assert "_experiments" not in copy.copy(posterior).__dict__


def test_a_posterior_keeps_the_root_attributes_and_refuses_what_is_not_one(sampled):
    *_, idata = sampled
    tagged = az.InferenceData(attrs={"lab": "ours"}, **{g: idata[g] for g in idata.groups()})
    assert Posterior.of(tagged).attrs == {"lab": "ours"}
    with pytest.raises(InputError, match="posterior: not a posterior"):
        Posterior.of(az.InferenceData(constant_data=idata.constant_data))
    with pytest.raises(InputError, match="posterior: not a posterior: a dict"):
        Posterior.of({})


def test_the_table_is_arviz_summary_with_the_ratio_and_the_autocorrelation_ess(sampled):
    """Issue 37, item 19: ``bj.summarize(...)["d_lat"]`` was the only summary, a dict of floats."""
    _, prior, chain, _, idata = sampled
    posterior = Posterior.of(idata)
    table = posterior.table()
    # A row per parameter (arviz's labels: width[v1_01, yaw] ...) and the ratio.
    assert list(table.index[:2]) == ["d_lat", "d_long"] and table.index[-1] == "ratio"
    assert len(table) == len(prior.names) + 1
    assert table["ess_autocorr"].iloc[:-1].notna().all()
    # The reference: arviz's own summary of the draws, and the ratio by hand.
    reference = az.summary(idata, var_names=["d_lat"], hdi_prob=0.94, round_to="none")
    assert table.loc["d_lat", "mean"] == pytest.approx(reference.loc["d_lat", "mean"], rel=1e-12)
    assert table.loc["d_lat", "hdi_97%"] == reference.loc["d_lat", "hdi_97%"]
    ratio = np.exp(chain[..., 0] - chain[..., 1])
    assert table.loc["ratio", "mean"] == pytest.approx(ratio.mean(), rel=1e-9)
    assert table.loc["d_lat", "ess_autocorr"] == 24.2 and np.isnan(
        table.loc["ratio", "ess_autocorr"]
    )
    # One home: summarize's numbers are the table's.
    summary = summarize(idata)
    assert summary["d_lat"]["sd"] == table.loc["d_lat", "sd"]
    assert posterior.table(round_to=2).loc["d_lat", "mean"] == round(summary["d_lat"]["mean"], 2)
