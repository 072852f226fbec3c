"""The population of the damping across groups of runs: stage 2's algebra, the groups CSV,
``bj.population`` and the ``population`` command (issue 27).

Stage 2's closed forms are checked against integrals computed here another
way: quadrature on a grid for the pooled and independent structures, plain
Monte Carlo over the hierarchy written out (mu, tau and each a_g drawn from
their priors) for the hierarchical one. The calibration over simulated
campaigns is in test_population_calibration.py.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import scipy.special
import scipy.stats
from conftest import messages

import bayes_jackal as bj
from bayes_jackal._runtime.errors import InputError
from bayes_jackal.inference import (
    Hierarchy,
    UnitPosterior,
    hierarchy,
    plan_units,
    unit_files,
    unit_posterior,
)
from bayes_jackal.inference.population_analysis import SKEWNESS_TOLERANCE, combine_summaries
from bayes_jackal.io import RunGroups, group_runs, read_groups, run_group
from bayes_jackal.posterior import Posterior, load_posterior

BOUNDS = np.array([[10.0, 1000.0], [10.0, 1000.0]])  # the Jackal's prior ranges [N s/m]
#: The midpoint rule's error over the 80 x 80 grid in log tau [nats]: the integral on a grid
#: twice as fine differs by less than this (test_the_tau_grid_is_fine_enough).
TAU_GRID_ERROR = 2e-3
LOG_WIDTH = math.log(100.0)  # each range's width on the log scale


def _units(covariates=(None, None, None)) -> list[UnitPosterior]:
    """Three units in two groups with correlated normal summaries, as one run's would be."""
    rng = np.random.default_rng(3)
    units = []
    for i, (group, covariate) in enumerate(zip("AAB", covariates, strict=True)):
        root = rng.normal(size=(2, 2)) * 0.05
        cov = root @ root.T + 0.002 * np.eye(2)
        mean = np.log([110.0, 30.0]) + rng.normal(0, 0.1, 2)
        units.append(UnitPosterior(f"u{i}", group, (f"u{i}",), mean, cov, covariate=covariate))
    return units


def _log_likelihood(units: list[UnitPosterior], theta: np.ndarray) -> np.ndarray:
    """sum_u log N(m_u | theta_u, S_u) for theta of shape (N, U, 2)."""
    return sum(
        scipy.stats.multivariate_normal(u.mean, u.cov).logpdf(theta[:, i])
        for i, u in enumerate(units)
    )


def _quadrature(log_values: np.ndarray, cell: float) -> float:
    return float(scipy.special.logsumexp(log_values) + math.log(cell))


def test_pooled_evidence_is_the_integral_over_the_one_damping():
    """pooled: the integral over mu, uniform on the box, of prod_u N(m_u | mu, S_u), on a
    0.0025-wide grid that resolves the summaries' sd of 0.04 and more."""
    units = _units()
    axis_lat = np.arange(3.8, 5.6, 0.0025)
    axis_long = np.arange(2.5, 4.3, 0.0025)
    grid = np.stack(np.meshgrid(axis_lat, axis_long, indexing="ij"), -1).reshape(-1, 2)
    theta = np.repeat(grid[:, None, :], len(units), axis=1)
    expected = _quadrature(_log_likelihood(units, theta), 0.0025**2) - 2 * math.log(LOG_WIDTH)
    assert Hierarchy(units, BOUNDS).log_integral("pooled") == pytest.approx(expected, abs=1e-6)


def test_independent_evidence_is_each_groups_integral():
    """independent: each group's damping uniform on the box; group B's one unit integrates to
    1 / W^2, group A's two units to the overlap of their normals (closed form)."""
    units = _units()
    a0, a1 = units[0], units[1]
    overlap = scipy.stats.multivariate_normal(a1.mean, a0.cov + a1.cov).logpdf(a0.mean)
    expected = overlap - 4 * math.log(LOG_WIDTH)
    value = Hierarchy(units, BOUNDS).log_integral("independent")
    assert value == pytest.approx(expected, abs=1e-9)


def test_slope_evidence_matches_monte_carlo():
    """pooled + slope: mu uniform on the box, each slope (of the scale and of the ratio) normal
    with sd ln 10 / 2 per covariate span. Monte Carlo with 400 000 draws of mu near the data
    and of the slopes from their prior; the tolerance is 4 standard errors of the estimate,
    computed from its weights."""
    units = _units(covariates=(0.3, 0.5, 0.4))
    z = (np.array([0.3, 0.5, 0.4]) - 0.4) / 0.2
    rng = np.random.default_rng(7)
    n = 400_000
    to_scale_ratio = np.array([[0.5, 0.5], [1.0, -1.0]])
    centre = np.mean([u.mean for u in units], axis=0)
    proposal = scipy.stats.multivariate_normal(centre, np.diag([0.3, 0.3]) ** 2)
    mu = proposal.rvs(n, random_state=rng)
    slopes = rng.normal(0.0, math.log(10.0) / 2, (n, 2)) @ np.linalg.inv(to_scale_ratio).T
    theta = mu[:, None, :] + z[None, :, None] * slopes[:, None, :]
    log_w = _log_likelihood(units, theta) - 2 * math.log(LOG_WIDTH) - proposal.logpdf(mu)
    estimate = scipy.special.logsumexp(log_w) - math.log(n)
    weights = np.exp(log_w - log_w.max())
    standard_error = np.std(weights) / np.mean(weights) / math.sqrt(n)
    value = Hierarchy(units, BOUNDS).log_integral("pooled + slope")
    assert value == pytest.approx(estimate, abs=4 * standard_error)


def test_a_slope_the_groups_absorb_costs_nothing():
    """Covariate constant within each group: in the independent structure the groups' own
    levels absorb any slope, which then integrates to its prior, so `independent + slope` has
    the evidence of `independent` (to rounding) and its slope draws follow the prior
    (sd ln 10 / 2 = 1.15 of the scale, to 3 % with 20 000 draws)."""
    units = _units(covariates=(0.3, 0.3, 0.5))  # group A at 0.3, group B at 0.5
    model = Hierarchy(units, BOUNDS)
    assert model.log_integral("independent + slope") == pytest.approx(
        model.log_integral("independent"), abs=1e-9
    )
    slope = model.draws("independent + slope", 20_000, rng=3)["slope"]
    scale = slope @ np.array([0.5, 0.5])
    assert np.std(scale) == pytest.approx(math.log(10.0) / 2, rel=0.03)


def test_hierarchical_evidence_matches_the_hierarchy_written_out():
    """hierarchical: mu uniform, log tau_scale and log tau_ratio uniform on [ln 0.01, 0],
    each group's (scale, ratio) ~ N(mu, diag(tau^2)): 2 000 000 draws of (mu near the data,
    tau, a_g) and the units' likelihood of them. Tolerance: 4 Monte Carlo se."""
    units = _units()
    rng = np.random.default_rng(11)
    n = 2_000_000
    to_scale_ratio = np.array([[0.5, 0.5], [1.0, -1.0]])
    centre = np.mean([to_scale_ratio @ u.mean for u in units], axis=0)
    mu = centre + 0.3 * rng.standard_normal((n, 2))
    log_q = scipy.stats.norm(centre, 0.3).logpdf(mu).sum(axis=1)
    tau = np.exp(rng.uniform(math.log(0.01), 0.0, (n, 2)))
    levels = mu[:, None, :] + tau[:, None, :] * rng.standard_normal((n, 2, 2))  # groups A, B
    theta = levels[:, [0, 0, 1], :] @ np.linalg.inv(to_scale_ratio).T
    # mu's prior: uniform on the box of (log d_lat, log d_long), area W^2, kept by the map
    log_w = _log_likelihood(units, theta) - 2 * math.log(LOG_WIDTH) - log_q
    estimate = scipy.special.logsumexp(log_w) - math.log(n)
    weights = np.exp(log_w - log_w.max())
    standard_error = np.std(weights) / np.mean(weights) / math.sqrt(n)
    value = Hierarchy(units, BOUNDS).log_integral("hierarchical")
    assert value == pytest.approx(estimate, abs=4 * standard_error + TAU_GRID_ERROR)


def test_the_tau_grid_is_fine_enough(monkeypatch):
    """The 80 x 80 midpoint grid in log tau against one of 160 x 160: within TAU_GRID_ERROR."""
    units = _units()
    coarse = Hierarchy(units, BOUNDS).log_integral("hierarchical")
    monkeypatch.setattr(hierarchy, "TAU_GRID", 160)
    fine = Hierarchy(units, BOUNDS).log_integral("hierarchical")
    assert coarse == pytest.approx(fine, abs=TAU_GRID_ERROR)


def test_a_vanishing_spread_is_the_pooled_structure():
    """With tau below 1e-5, far under every summary's sd (0.04 at least), the hierarchy is one
    damping: the two differ by O(tau^2 / sd^2) < 1e-7 nats, far inside the 1e-3 allowed."""
    units = _units()
    narrow = Hierarchy(units, BOUNDS, tau_range=(1e-6, 1e-5))
    assert narrow.log_integral("hierarchical") == pytest.approx(
        narrow.log_integral("pooled"), abs=1e-3
    )


def test_pooled_draws_follow_the_product_of_the_normals():
    """pooled: mu's posterior is the product of the units' normals (precision-weighted mean);
    20 000 draws give its mean to 0.05 sd and its sd to 2 % (about 5 Monte Carlo se)."""
    units = _units()
    precision = sum(np.linalg.inv(u.cov) for u in units)
    cov = np.linalg.inv(precision)
    mean = cov @ sum(np.linalg.inv(u.cov) @ u.mean for u in units)
    draws = Hierarchy(units, BOUNDS).draws("pooled", 20_000, rng=1)
    sd = np.sqrt(np.diag(cov))
    np.testing.assert_allclose(draws["mu"].mean(axis=0), mean, atol=0.05 * sd.min())
    np.testing.assert_allclose(draws["mu"].std(axis=0), sd, rtol=0.02)
    np.testing.assert_allclose(draws["groups"][:, 0], draws["mu"])
    assert draws["tau"] is None and draws["slope"] is None


def test_hierarchical_draws_shrink_groups_toward_each_other():
    """Group B (one unit) pulled toward group A: its mean lies between its own summary
    and the pooled damping, and its sd is no larger than its own."""
    units = _units()
    model = Hierarchy(units, BOUNDS)
    group_b = model.draws("hierarchical", 20_000, rng=2)["groups"][:, 1]
    pooled = model.draws("pooled", 20_000, rng=2)["mu"].mean(axis=0)
    own = units[2].mean
    between = (group_b.mean(axis=0) - own) * (pooled - own)
    assert np.all(between >= 0)
    # 2 %: four times the Monte Carlo error of an sd from 20 000 draws, 1 / sqrt(2 n) = 0.5 %.
    assert np.all(group_b.std(axis=0) <= np.sqrt(np.diag(units[2].cov)) * 1.02)


def test_stage_2_is_calibrated_and_shrinks_on_normal_units():
    """Stage 2 alone, on 120 campaigns of 3 floors whose units are exact normals (sd 0.023 per
    log damping, correlated at 0.99, as 5 pooled runs give): the floors' log dampings drawn
    with sd 0.03 around log(110, 30).

    - The 94 % HDIs hold the truth in 360 floors within the binomial bound (d_lat alone:
      d_long moves with it).
    - Shrinkage: the intervals are narrower than alone on average, the errors smaller on
      average. An outlying floor's interval can be wider, by how uncertain the spread leaves
      its pull; never by more than 8 % here.
    """
    rng = np.random.default_rng(27)
    cov = 0.023**2 * np.array([[1.0, 0.99], [0.99, 1.0]])
    inside, widths, errors = [], [], []
    for _ in range(120):
        truth = np.log([110.0, 30.0]) + 0.03 * rng.standard_normal((3, 2))
        units = [
            UnitPosterior(g, g, (g,), rng.multivariate_normal(truth[i], cov), cov)
            for i, g in enumerate("ABC")
        ]
        model = Hierarchy(units, BOUNDS)
        joint = model.draws("hierarchical", 4000, rng=1)["groups"][..., 0]
        alone = model.draws("independent", 4000, rng=1)["groups"][..., 0]
        for g in range(3):
            low, high = np.percentile(joint[:, g], [3, 97])
            low_alone, high_alone = np.percentile(alone[:, g], [3, 97])
            inside.append(low <= truth[g, 0] <= high)
            widths.append((high - low) / (high_alone - low_alone))
            errors.append(
                (abs(joint[:, g].mean() - truth[g, 0]), abs(alone[:, g].mean() - truth[g, 0]))
            )
    # 0.1 % quantile of Binomial(360, 0.94)
    assert sum(inside) >= scipy.stats.binom.ppf(0.001, len(inside), 0.94)
    # Measured: mean width ratio 0.88 (its standard error over 360 floors about 0.003), the
    # widest 1.07 (1.08 over 1 350 floors at spreads 0.03-0.1), the error ratio 0.86.
    assert np.mean(widths) < 0.95 and max(widths) < 1.1
    joint_error, alone_error = np.mean(errors, axis=0)
    assert joint_error < 0.9 * alone_error


def test_unit_posterior_flags_what_a_normal_cannot_summarise():
    """Skewed draws (log-damping gamma-distributed, shape 2: skewness sqrt 2) are flagged by
    their skewness (their 94 % ellipse still holds 93.7 % of them); draws piled at the prior's
    floor are flagged."""
    rng = np.random.default_rng(4)
    skewed = np.exp(
        np.stack([4.0 + rng.gamma(2.0, 0.1, 8000), 3.4 + rng.normal(0, 0.05, 8000)], 1)
    )
    unit = unit_posterior("r1", "A", skewed, BOUNDS)
    # Sample skewness of a gamma varies far more than a normal's sqrt(6 / n): 1.26 here.
    assert unit.skewness > 2 * SKEWNESS_TOLERANCE
    floor = np.exp(
        np.stack([rng.uniform(np.log(10.0), np.log(12.0), 8000), np.full(8000, 3.4)], 1)
    )
    assert unit_posterior("r2", "A", floor, BOUNDS).at_bound == ("d_lat",)


def test_a_covariate_must_be_given_for_every_unit_and_vary():
    with pytest.raises(InputError, match="unit 'u2' has none"):
        Hierarchy(_units(covariates=(0.3, 0.4, None)), BOUNDS)
    with pytest.raises(InputError, match=r"two finite values at least, got \[0.3\]"):
        Hierarchy(_units(covariates=(0.3, 0.3, 0.3)), BOUNDS)
    with pytest.raises(InputError, match="unknown structure 'pooled \\+ slope'"):
        Hierarchy(_units(), BOUNDS).log_integral("pooled + slope")


# -- the groups CSV ---------------------------------------------------------------------


def test_read_groups_takes_odd_headers_blank_lines_and_a_byte_order_mark(tmp_path):
    path = tmp_path / "groups.csv"
    text = "\ufeff Bag ,Condition, SPEED ,surface\n\nv1_01.bag,tiles,0.3,ceramic\n"
    text += "v1_02.bag,carpet,,wool\n"
    path.write_text(text, encoding="utf-8")
    table = read_groups(path)
    assert table.groups == {"v1_01.bag": "tiles", "v1_02.bag": "carpet"}
    assert table.covariates == {"v1_01.bag": {"speed": 0.3}, "v1_02.bag": {}}
    assert table.label_of("/data/lab/v1_02.bag") == "carpet"
    assert table.label_of("v1_02") == "carpet"
    assert table.covariate_names == ("speed",)


@pytest.mark.parametrize(
    ("text", "field", "message"),
    [
        ("name,speed\nv1,0.3\n", "header", "no column headed 'group'"),
        ("run,group\nv1,A\nv1,B\n", "row 3", "run 'v1' is listed twice"),
        ("run,group\nv1,\n", "row 2", "empty 'group'"),
        ("run,group,speed\nv1,A,0.3\nv2,A,inf\n", "row 3, column 'speed'", "finite number"),
        ("", None, "the groups CSV is empty"),
        # An unquoted decimal comma splits a speed in two: refused, not read as 0.
        ("run,group,speed\nv1_01,A,0,3\n", "row 2", r"4 cells under a header of 3 \(an unq"),
        # Two speed columns: neither is guessed.
        ("run,group,speed,Speed\nv1,A,0.3,0.4\n", "header", "names 'speed' twice"),
    ],
)
def test_read_groups_refuses_bad_tables_naming_file_row_and_column(tmp_path, text, field, message):
    path = tmp_path / "groups.csv"
    path.write_text(text)
    with pytest.raises(InputError, match=message) as caught:
        read_groups(path)
    assert caught.value.source == str(path) and caught.value.field == field


def test_a_covariate_header_with_its_unit_is_the_covariate(tmp_path):
    path = tmp_path / "groups.csv"
    path.write_text("run,group,speed [m/s],mass (kg)\nv1,A,0.3,20\nv2,B,0.6,21\n")
    assert read_groups(path).covariates == {
        "v1": {"speed": 0.3, "mass": 20.0},
        "v2": {"speed": 0.6, "mass": 21.0},
    }


def test_a_speed_left_empty_for_one_run_is_said_not_dropped_in_silence(floor_runs):
    speeds = {"r0": {"speed": 0.3}, "r1": {"speed": 0.6}, "r2": {"speed": 0.3}, "r3": {}}
    plan = plan_units(floor_runs, RunGroups(FLOORS, speeds, source="groups.csv"),
                      noise="per-experiment")  # fmt: skip
    assert plan.covariate is None
    (note,) = plan.notes
    assert note["kind"] == "covariate-incomplete" and "'r3' has none" in note["message"]
    assert plan_units(floor_runs, FLOORS).notes == []  # no speed anywhere: nothing to say


def test_a_covariate_named_after_a_text_column_is_said_to_hold_text(floor_runs, tmp_path):
    # It read "run 'r0' has no 'surface'" of a table that gives every run one
    # (issue 37, item 13).
    path = tmp_path / "groups.csv"
    rows = "".join(f"{run},{label},{label}s\n" for run, label in FLOORS.items())
    path.write_text("run,group,surface\n" + rows)
    assert read_groups(path).text_columns == ("surface",)
    with pytest.raises(InputError, match="the column 'surface' holds text, not numbers") as caught:
        plan_units(floor_runs, path, covariate="surface", noise="per-experiment")
    assert caught.value.source == str(path) and caught.value.field == "surface"


@pytest.mark.parametrize(
    ("covariates", "field"),
    [
        ([0.3], "provenance.covariates"),
        ({"speed": "fast"}, "provenance.covariates.speed"),
        ({"speed": None}, "provenance.covariates.speed"),
        ({"speed": float("nan")}, "provenance.covariates.speed"),
    ],
)
def test_bad_covariates_in_a_runs_provenance_are_named(covariates, field):
    # A list, text, None or NaN raised AttributeError or ValueError (exit 1).
    run = bj.simulate_experiment(bj.load_profile(), 110.0, 30.0, rng=1, name="r1")
    run.provenance.update(group="A", covariates=covariates)
    with pytest.raises(InputError) as caught:
        run_group(run, None)
    assert caught.value.field == field and caught.value.source == run.source


def test_speeds_whose_range_overflows_a_float_are_refused_without_a_numpy_warning():
    with pytest.raises(InputError, match="span more than a float holds"):
        Hierarchy(_units((-1e308, 1e308, 0.0)), BOUNDS)


def test_a_run_is_matched_to_its_row_by_path_file_name_or_name_and_never_guessed():
    table = RunGroups({"a/v1.bag": "A", "b/v1.bag": "B", "speed_0.3": "slow"}, source="g.csv")
    assert table.label_of("/data/b/v1.bag") == "B"  # the end of its path
    assert table.label_of("speed_0.5") is None  # ".5" is no file's suffix
    with pytest.raises(InputError, match=r"matches the rows \['a/v1.bag', 'b/v1.bag'\]"):
        table.label_of("v1")  # by name alone, two rows


def test_a_speed_written_with_a_decimal_comma_is_refused_not_dropped(tmp_path):
    path = tmp_path / "groups.csv"
    path.write_text('run,group,speed\nv1,A,"0,3"\nv2,B,"0,4"\n')
    with pytest.raises(InputError, match="speed must be a number, got '0,3'") as caught:
        read_groups(path)
    assert caught.value.field == "row 2, column 'speed'"
    path.write_text("run,group,load\nv1,A,12\nv2,B,heavy\n")  # numbers and text mixed
    with pytest.raises(InputError, match="load must be a number, got 'heavy'"):
        read_groups(path)


def test_group_runs_names_a_run_without_a_group():
    robot = bj.load_profile()
    runs = [bj.simulate_experiment(robot, 110.0, 30.0, rng=s, name=f"r{s}") for s in (1, 2)]
    with pytest.raises(InputError, match="experiment 'r2' has no group"):
        group_runs(runs, RunGroups({"r1": "A"}, source="groups.csv"))
    runs[1].provenance.update(group="B")
    runs[0].provenance.update(group="A")
    assert list(group_runs(runs)) == ["A", "B"]


# -- bj.population and the command ------------------------------------------------------

#: Four runs, two per floor; the carpet's d_long a third higher (110 N s/m of d_lat on both),
#: so that their ratio d_lat / d_long, which the yaw rate alone pins, differs.
TRUE_D_LONG = (30.0, 30.0, 40.0, 40.0)
FLOORS = {"r0": "tiles", "r1": "tiles", "r2": "carpet", "r3": "carpet"}


@pytest.fixture(scope="module")
def floor_runs():
    robot = bj.load_profile()
    return [
        bj.simulate_experiment(robot, 110.0, d_long, rng=seed, name=f"r{seed}")
        for seed, d_long in enumerate(TRUE_D_LONG)
    ]


@pytest.fixture(scope="module")
def floor_population(floor_runs, tmp_path_factory):
    """The library's population of the four runs, units saved, and what it said."""
    folder = tmp_path_factory.mktemp("population")
    with messages() as said:
        return _population(floor_runs, folder, groups=FLOORS), folder, said


def _population(runs, folder, **options):
    return bj.population(
        runs,
        family="white",
        channels=["yaw"],
        seed=1,
        max_steps=400,
        progress=False,
        out=folder,
        **options,
    )


def test_population_json_and_its_units_saved_and_reused(floor_runs, floor_population):
    result, folder, said = floor_population
    summary = json.loads(json.dumps(result.to_dict()))  # JSON-ready
    assert {"groups", "population", "speed_dependence", "evidence", "best", "warnings"} <= set(
        summary
    )
    assert summary["speed_dependence"] is None
    assert set(summary["evidence"]) == {"pooled", "hierarchical", "independent"}
    assert result.log_bayes_factor("pooled", result.best)[0] < -3  # the ratios differ
    # Each floor's ratio of its dampings' means, against the truth (110/30, 110/40): the
    # yaw rate pins it to about 1 %, so 5 % holds with room for the shrinkage between them.
    for label, d_long in (("tiles", 30.0), ("carpet", 40.0)):
        group = summary["groups"][label]
        ratio = group["d_lat"]["mean"] / group["d_long"]["mean"]
        assert ratio == pytest.approx(110.0 / d_long, rel=0.05)
    # The yaw rate alone does not pin the dampings' scale: each floor's d_long runs into
    # its prior's floor of 10 N s/m, and the result says so, as it says two groups are few.
    kinds = [w["kind"] for w in summary["warnings"]]
    assert kinds.count("few-groups") == 1 and "prior-boundary" in kinds
    assert "approximate" in summary["verdict"]
    assert any("log Z" in line for line in said)
    for path in unit_files(folder, ["tiles", "carpet"], "white").values():
        assert path.is_file()
    with messages() as again:
        rerun = _population(floor_runs, folder, groups=FLOORS)
    assert any("reus" in line for line in again) and not any("log Z" in line for line in again)
    assert rerun.to_dict()["evidence"] == summary["evidence"]


def test_shared_noise_refuses_a_group_of_several_speeds_before_sampling(floor_runs, tmp_path):
    table = RunGroups(FLOORS, {name: {"speed": 0.2 + 0.1 * i} for i, name in enumerate(FLOORS)})
    with pytest.raises(InputError, match="group 'tiles' pools runs at speed") as refused:
        _population(floor_runs, tmp_path, groups=table)
    assert not (tmp_path / "units").exists()
    # The way out is named for both callers (issue 37: it gave only the Python keyword).
    assert "noise='per-experiment'; on the command line --noise per-experiment" in str(
        refused.value
    )


def test_one_group_is_refused_before_sampling(floor_runs, tmp_path):
    with pytest.raises(InputError, match="a population needs two groups at least"):
        _population(floor_runs, tmp_path, groups=dict.fromkeys(FLOORS, "tiles"))
    assert not (tmp_path / "units").exists()


def test_analyse_refuses_a_bad_groups_file_before_any_work(floor_runs, tmp_path):
    from bayes_jackal.io.experiment import write_netcdf
    from bayes_jackal.workflow.analysis import analyse_logs

    paths = [write_netcdf(run, tmp_path / f"{run.name}.nc") or tmp_path / f"{run.name}.nc"
             for run in floor_runs]  # fmt: skip
    with pytest.raises(InputError, match="experiment 'r3' has no group"):
        analyse_logs(paths, tmp_path / "out", groups={"r0": "A", "r1": "A", "r2": "B"})
    assert not (tmp_path / "out" / "grid.json").exists()


def test_population_command_writes_json_plot_and_refuses_a_bad_table(
    cli, tmp_path, floor_runs, floor_population
):
    from bayes_jackal.io.experiment import write_netcdf

    for run in floor_runs:
        write_netcdf(run, tmp_path / f"{run.name}.nc")
    (tmp_path / "groups.csv").write_text(
        "run,group\n" + "".join(f"{run}.nc,{label}\n" for run, label in FLOORS.items())
    )
    args = ["population", *[f"{r}.nc" for r in FLOORS], "--groups", "groups.csv"]
    flags = ["--family", "white", "--channels", "yaw", "--max-steps", "400", "--seed", "1"]
    result = cli([*args, "--out", "pop", *flags, "--json", "--no-progress"], tmp_path, timeout=300)
    assert result.code == 0, result.stderr
    summary = json.loads(result.stdout)
    # The command is bj.population: the same seed, the same chains, the same evidence.
    library = json.loads(json.dumps(floor_population[0].to_dict()))
    assert summary["evidence"] == library["evidence"]
    assert json.loads((tmp_path / "pop" / "population.json").read_text()) == summary
    assert (tmp_path / "pop" / "population.png").stat().st_size > 0
    (tmp_path / "bad.csv").write_text("run,group\nr0.nc,tiles\n")
    bad = cli([*args[:-1], "bad.csv", "--out", "pop2", *flags], tmp_path)
    assert bad.code == 2
    assert "experiment 'r1' has no group" in bad.stderr and "Traceback" not in bad.stderr
    # A file where the units' folder goes is refused before any unit is sampled.
    (tmp_path / "pop3").mkdir()
    (tmp_path / "pop3" / "units").write_text("keep me")
    blocked = cli([*args, "--out", "pop3", *flags], tmp_path)
    assert blocked.code == 2, blocked.stderr
    assert "--out pop3/units: is an existing file; give a folder" in blocked.stderr
    assert sorted(p.name for p in (tmp_path / "pop3").iterdir()) == ["units"]


def test_the_population_command_fits_with_its_modelling_flags(cli, tmp_path, floor_runs):
    # population once dropped --steady and --damping (its units fitted every sample, one
    # damping); its flags now reach the units through the one FitOptions every verb builds.
    # The units' task records the window, the priors and the walkers (not the damping model,
    # which these runs at one speed cannot take).
    from bayes_jackal.io.experiment import write_netcdf

    for run in floor_runs:
        write_netcdf(run, tmp_path / f"{run.name}.nc")
    (tmp_path / "groups.csv").write_text(
        "run,group\n" + "".join(f"{run}.nc,{label}\n" for run, label in FLOORS.items())
    )
    args = ["population", *[f"{r}.nc" for r in FLOORS], "--groups", "groups.csv", "--steady"]
    args += ["--prior", "d_lat", "50", "400", "--walkers", "40"]
    flags = ["--family", "white", "--channels", "yaw", "--max-steps", "100", "--seed", "1"]
    result = cli([*args, "--out", "pop", *flags, "--no-progress"], tmp_path, timeout=300)
    assert result.code == 0, result.stderr
    for path in unit_files(tmp_path / "pop", ["tiles", "carpet"], "white").values():
        task = Posterior.of(load_posterior(path)).metadata.task
        assert task["likelihood"]["steady"] is True, path
        assert (task["priors"]["low"][0], task["priors"]["high"][0]) == (50.0, 400.0)
        assert task["walkers"] == 40


def _speed_groups(ratio: float) -> bj.inference.Population:
    """Five units at 0.3 m/s (group slow) and five at 0.6 m/s (fast), the damping
    ``ratio`` times higher at the higher speed: each group at one speed (issue 37, item 20)."""
    rng = np.random.default_rng(20)
    units = []
    for i in range(10):
        group, speed = ("slow", 0.3) if i < 5 else ("fast", 0.6)
        cov = np.diag([0.05, 0.04]) ** 2  # a unit's sd of log d: 4-5 %
        mean = np.log([110.0, 30.0]) + (speed == 0.6) * math.log(ratio)
        mean = rng.multivariate_normal(mean, cov)
        units.append(UnitPosterior(f"u{i}", group, (f"u{i}",), mean, cov, covariate=speed,
                                   log_evidence=0.0, evidence_error=0.1))  # fmt: skip
    return combine_summaries(units, BOUNDS, family="white", covariate="speed", seed=1)


def test_a_speed_that_only_the_groups_carry_is_said_to_be_the_groups_difference():
    # With one speed per group, "the groups differ" and "the damping depends on
    # speed" are one model: the slope structure and the hierarchical one tie
    # (ln B about -2 by Occam's factor, so the old verdict read "not shown to
    # depend on speed" beside a ratio of 1.5 [1.4, 1.6]). The verdict says so
    # and weighs the slope against one damping for all.
    dependence = _speed_groups(1.5).speed_dependence()
    assert dependence["confounded"] and dependence["detected"], dependence
    assert dependence["structure"] == "pooled + slope" and dependence["against"] == "pooled"
    assert dependence["log_bayes_factor"] > 3
    assert "only the groups carry" in dependence["verdict"], dependence["verdict"]
    ratio = dependence["slope"]["d_lat"]["ratio_across_range"]
    assert ratio["hdi_3%"] < 1.5 < ratio["hdi_97%"]
    # Equal dampings at both speeds: nothing detected, and the same caveat.
    same = _speed_groups(1.0).speed_dependence()
    assert same["confounded"] and not same["detected"], same
    assert "only the groups carry" in same["verdict"]


def test_speeds_that_vary_within_a_group_are_not_confounded():
    units = []
    for i in range(8):  # groups A and B, each with units at 0.3 and 0.6 m/s
        mean, cov, speed = np.log([110.0, 30.0]), 1e-3 * np.eye(2), (0.3, 0.6)[(i // 2) % 2]
        units.append(UnitPosterior(f"u{i}", "AB"[i % 2], (f"u{i}",), mean, cov, covariate=speed,
                                   log_evidence=0.0, evidence_error=0.1))  # fmt: skip
    dependence = combine_summaries(
        units, BOUNDS, family="white", covariate="speed", seed=1
    ).speed_dependence()
    assert not dependence["confounded"]
    assert "only the groups carry" not in dependence["verdict"]
