"""Time stamps as real logs have them: jittered, repeated, out of order, missing, irregular.

The stamp fixtures are written here, independently of the package:

- ``gazebo_stamps``: a 1 kHz simulator that stamps each step with a clock
  lagging or leading by a whole number of ms, -2..+2, a Markov chain (down
  by one, or up by one to four, capped). Each step is then 0 ms (a
  repeated stamp), 1 ms, or 2-5 ms, and there is still exactly one sample
  per millisecond, like the public Gazebo log of issue 10 (14 % repeated
  stamps, gaps of 2-5 ms).
- clean grids with rows removed, swapped or duplicated, and log-uniform
  random steps (no clock at all).

The end-to-end test writes one simulated 1 kHz run twice as CSV with odd
column names, once with clean and once with Gazebo-like stamps, and checks
that ``grid`` and ``sample`` (command line and library) give the same
answer: the reader restores the stamps exactly to k x 1 ms, so the
experiments are identical and, with the same seed, so are the chains.
"""

from __future__ import annotations

import json
import re
import warnings

import numpy as np
import pytest

from bayes_jackal._runtime.errors import DataError, InputError
from bayes_jackal.cli import main
from bayes_jackal.inference.chains import SamplerSettings
from bayes_jackal.inference.sampling import sample_posterior
from bayes_jackal.io.simulate import Series, simulate_experiment
from bayes_jackal.io.stamps import GRID, ONE_PER_TICK, UNIFORM, sort_stamps, uniform_clock
from bayes_jackal.io.tables import load_experiment, read_csv, write_csv
from bayes_jackal.likelihood.residual_likelihood import ResidualLikelihood
from bayes_jackal.model.robot import default_profile_path, load_profile
from bayes_jackal.posterior.posterior import load_posterior
from bayes_jackal.thesis.gridsearch import damping_grid, grid_search

MS = 1e-3


def gazebo_stamps(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Stamps [s] of n samples at 1 kHz, each lagging its tick by -2..+2 ms; and the lags [ms]."""
    lag = np.empty(n, np.int64)
    current = 0
    draw, jump = rng.random(n), rng.integers(1, 5, n)
    for k in range(n):  # a Markov chain: each lag depends on the one before
        if draw[k] < 0.17 and current > -2:
            current -= 1
        elif draw[k] > 0.91:
            current = min(2, current + jump[k])
        lag[k] = current
    return (np.arange(n) + lag) * MS, lag


@pytest.fixture(scope="module")
def gazebo() -> tuple[np.ndarray, np.ndarray]:
    return gazebo_stamps(16_000, np.random.default_rng(2024))


def test_the_fixture_looks_like_the_gazebo_log(gazebo):
    stamps, _ = gazebo
    steps = np.rint(np.diff(stamps) / MS).astype(int)
    assert 0.12 < np.mean(steps == 0) < 0.16  # ~14 % repeated stamps
    assert set(np.unique(steps[steps > 1])) == {2, 3, 4, 5}  # gaps of 2-5 ms
    assert (steps >= 0).all()
    # One sample per ms: 16,000 samples over 16 s, to within the lag.
    assert abs((stamps[-1] - stamps[0]) / MS + 1 - len(stamps)) <= 4


def test_jittered_clock_is_restored_exactly_and_reported(gazebo):
    stamps, lag = gazebo
    clock = uniform_clock(stamps)
    # The true clock is k x 1 ms; the lags average ~0, so the origin is tick 0.
    np.testing.assert_array_equal(clock.t, np.arange(len(stamps)) * MS)
    np.testing.assert_array_equal(clock.rows, np.arange(len(stamps)))
    np.testing.assert_array_equal(clock.resample(lag), lag)  # no value moved
    base = clock.provenance
    assert base["clock"] == ONE_PER_TICK
    assert base["rate"] == 1000.0 and base["rate_source"] == "fitted, whole Hz"
    # With the clock restored, each stamp's deviation is its lag.
    jitter = base["jitter"]
    assert jitter["sd"] == pytest.approx(np.std(lag * MS), rel=1e-9)
    assert jitter["max"] == pytest.approx(np.abs(lag).max() * MS, rel=1e-9)
    assert jitter["repeated"] == np.count_nonzero(np.diff(stamps) == 0)
    assert jitter["backward"] == 0
    assert base["interpolated"] == base["dropped"] == 0
    [repair] = clock.repairs
    assert "jittered around a uniform 1000 Hz clock" in repair
    assert f"{jitter['repeated']} repeated" in repair


def test_declared_rate_gives_the_same_clock(gazebo):
    stamps, _ = gazebo
    clock = uniform_clock(stamps, rate=1000)
    np.testing.assert_array_equal(clock.t, np.arange(len(stamps)) * MS)
    assert clock.provenance["rate_source"] == "declared"


@pytest.mark.parametrize(
    ("rate", "pattern"),
    [
        (500.0, r"less than half the 0\.002 s step.*drifts .* from the declared 500 Hz"),
        (999.0, r"steps off the nearest tick of a 999 Hz clock.*from the declared 999 Hz"),
    ],
)
def test_declared_rate_that_contradicts_the_stamps(gazebo, rate, pattern):
    with pytest.raises(DataError, match=rf"^run\.csv: t: time is not uniformly .*{pattern}"):
        uniform_clock(gazebo[0], rate=rate, source="run.csv")


def test_clean_stamps_are_uniform_without_repairs():
    t = np.round(np.arange(500) / 72.0, 10)  # as a CSV written with 10 digits holds them
    clock = uniform_clock(t)
    assert clock.provenance["clock"] == UNIFORM and clock.repairs == []
    assert clock.provenance["rate"] == 72.0
    np.testing.assert_allclose(clock.t, t, rtol=0, atol=1e-10)
    # A rate that is not whole stays as it is: the stamps tell it apart.
    odd = uniform_clock(np.arange(500) / 72.3)
    assert odd.provenance["rate"] == pytest.approx(72.3, rel=1e-12)
    assert odd.provenance["rate_source"] == "fitted"


def test_a_dropout_is_filled_by_linear_interpolation():
    t = np.delete(np.arange(100) * 0.01, [40, 41, 42])
    values = 3.0 - 2.0 * t  # a line: interpolation must give it exactly
    clock = uniform_clock(t, row_name=lambda i: f"line {i + 2}")
    assert clock.provenance["clock"] == GRID
    np.testing.assert_allclose(clock.t, np.arange(100) * 0.01, rtol=0, atol=1e-15)
    np.testing.assert_allclose(clock.resample(values), 3.0 - 2.0 * clock.t, atol=1e-12)
    assert clock.provenance["interpolated"] == 3
    [repair] = clock.repairs
    assert "1 gap of at most 4 steps filled with 3 linearly interpolated samples" in repair
    assert "after line 41, t = 0.39 s" in repair


def test_a_gap_longer_than_max_gap_splits_and_the_longest_piece_is_kept():
    t = np.delete(np.arange(1000) * MS, np.arange(300, 400))
    clock = uniform_clock(t)
    np.testing.assert_allclose(clock.t, np.arange(400, 1000) * MS, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(clock.rows, np.arange(300, 900))
    text = " ".join(clock.repairs)
    assert "gap of 0.101 s (101 steps) after sample 299" in text
    assert "longer than max_gap 0.005 s" in text and "the longest piece" in text
    # A larger max_gap fills the same gap instead.
    filled = uniform_clock(t, max_gap=0.2)
    assert len(filled.t) == 1000 and filled.provenance["interpolated"] == 100


def test_out_of_order_and_duplicated_rows_are_sorted_and_dropped_as_bags_do():
    t = np.arange(200) * 0.01
    order = np.arange(200)
    order[[50, 51]] = [51, 50]  # delivered out of order
    order = np.insert(order, 120, 119)  # row 119 recorded twice
    clock = uniform_clock(t[order])
    assert clock.provenance["clock"] == GRID
    np.testing.assert_allclose(clock.t, t, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(clock.resample(order), np.arange(200))
    assert clock.repairs == [
        "t: 1 out-of-order stamps; sorted",
        "t: 1 duplicate stamps (first at sample 120); kept the first message of each",
    ]


def test_sort_stamps_in_nanoseconds_names_the_clock_jump():
    stamps = np.array([0, 10, 20, 30, 5, 40]) * 1_000_000
    order, repairs = sort_stamps(
        stamps,
        max_backstep=0.1e9,
        where=str,
        source="a.bag",
        field="/imu",
        label="/imu",
        unit=1e-9,
    )
    np.testing.assert_array_equal(stamps[order], np.sort(stamps))
    assert repairs == ["/imu: 1 out-of-order stamps; sorted"]
    with pytest.raises(
        DataError, match=r"^a\.bag: /imu: timestamps go backwards by 0\.025 s at 4 "
    ):
        sort_stamps(
            stamps,
            max_backstep=0.01e9,
            where=str,
            source="a.bag",
            field="/imu",
            label="/imu",
            unit=1e-9,
        )


@pytest.mark.parametrize("value", [1e308, -1e308, 1e307, 1e200, 1e16])
@pytest.mark.parametrize("row", [0, 100, 1998, 1999])
def test_a_stamp_beyond_any_clock_is_a_clock_jump_naming_line_and_value(row, value):
    # One corrupt stamp overflowed the clock's fit (ValueError: cannot convert float NaN
    # to integer, or an AttributeError), or was said in hundreds of digits; no warning now
    # (they are errors here).
    t = np.arange(2000) / 72.0
    t[row] = value
    with pytest.raises(DataError) as info:
        uniform_clock(t, source="x.csv", row_name=lambda i: f"line {i + 2}")
    message = str(info.value)
    assert message.startswith(f"x.csv: t: a clock jump at line {row + 2}: t = {value:.4g} s,")
    assert re.search(r"\d{20}", message) is None  # compact numbers


def test_a_huge_backward_step_is_said_compactly():
    stamps = np.array([0.0, 1e200, 2.0, 3.0])
    with pytest.raises(DataError, match=r"backwards by 1e\+200 s at 2 \(more than max_gap 1 s"):
        sort_stamps(stamps, max_backstep=1.0, where=str, source="x.csv", field="t", label="t")


def test_a_truly_irregular_series_is_an_error_naming_line_and_stamp():
    rng = np.random.default_rng(5)
    t = np.cumsum(np.exp(rng.uniform(np.log(1e-4), np.log(1e-2), 2000)))
    with pytest.raises(DataError) as info:
        uniform_clock(t, source="log.csv", row_name=lambda i: f"line {i + 2}")
    message = str(info.value)
    match = re.search(r"not uniformly sampled at line (\d+): t = ([0-9.e-]+) s", message)
    assert match, message
    line, value = int(match.group(1)), float(match.group(2))
    assert value == pytest.approx(t[line - 2], rel=1e-9)
    assert "no uniform clock fits" in message
    assert "declare it (--rate HZ" in message and "resample" in message


def test_continuous_jitter_is_one_sample_per_tick():
    rng = np.random.default_rng(8)
    t = np.arange(5000) * 0.01 + rng.normal(0.0, 0.002, 5000)  # sd 0.2 steps, no grid
    clock = uniform_clock(t)
    assert clock.provenance["clock"] == ONE_PER_TICK
    assert clock.provenance["rate"] == 100.0
    np.testing.assert_allclose(clock.t, np.arange(5000) * 0.01, rtol=0, atol=1e-12)
    # sd of the deviations: 2 ms, estimated from 5000 draws (relative se 1 %).
    assert clock.provenance["jitter"]["sd"] == pytest.approx(0.002, rel=0.05)


def test_a_file_in_reverse_time_order_is_sorted():
    # Newest row first: every step is -10 ms. The default max_gap is 5 steps of
    # the sorted stamps (50 ms), so no step is a clock jump.
    t = np.arange(50) * 0.01
    clock = uniform_clock(t[::-1])
    np.testing.assert_allclose(clock.t, t, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(clock.resample(np.arange(50)[::-1]), np.arange(50))
    assert clock.repairs == [
        "t: 49 out-of-order stamps (in reverse time order throughout); sorted"
    ]
    assert clock.provenance["jitter"]["backward"] == 49


def test_a_gapless_grid_with_a_duplicate_and_jitter_is_a_grid_without_gaps():
    # 0.1 % of a step of jitter (below the uniform tolerance) and one row twice.
    rng = np.random.default_rng(1)
    t = np.arange(200) * 0.01 + rng.normal(0.0, 1e-5, 200)
    clock = uniform_clock(np.insert(t, 100, t[99]))
    base = clock.provenance
    assert base["clock"] == GRID == "grid"
    assert (base["interpolated"], base["dropped"], base["samples"]) == (0, 1, 200)
    assert base["jitter"]["repeated"] == 1
    assert clock.repairs == [
        "t: 1 duplicate stamps (first at sample 100); kept the first message of each"
    ]


def test_jitter_covers_only_the_piece_kept():
    # A clean 1 kHz piece of 600 samples after a 100-step gap; the 300 stamps
    # before it, cut off, are jittered by 0.2 steps (within the grid tolerance
    # of 0.25) and two of them are repeated.
    rng = np.random.default_rng(4)
    early = np.arange(300) * MS + rng.uniform(-0.2, 0.2, 300) * MS
    early = np.insert(early, [10, 20], early[[9, 19]])
    t = np.concatenate([early, np.arange(400, 1000) * MS])
    clock = uniform_clock(t)
    np.testing.assert_allclose(clock.t, np.arange(400, 1000) * MS, rtol=0, atol=1e-12)
    jitter = clock.provenance["jitter"]
    # The clock rounds to 1 kHz and a whole origin, on which the kept stamps
    # lie exactly (up to float rounding): no jitter, and none reported.
    assert jitter["max_steps"] < 1e-9
    assert jitter["repeated"] == jitter["backward"] == 0
    assert not any("jittered" in repair for repair in clock.repairs)
    assert clock.provenance["dropped"] == 302


@pytest.mark.parametrize(("keyword", "value"), [("rate", 0.0), ("rate", -5), ("max_gap", np.nan)])
def test_rate_and_max_gap_must_be_positive(keyword, value):
    with pytest.raises(InputError, match=rf"^{keyword}: must be a positive number"):
        uniform_clock(np.arange(10) * 0.1, **{keyword: value})


# --------------------------------------------------------------------------- end to end

ROBOT = load_profile()
#: Odd column names, as a lab's logger writes them.
NAMES = {
    "t": "time_s",
    "yaw_rate": "gyro_z",
    "omega_r": "wheel_r",
    "omega_l": "wheel_l",
    "vx": "v_fwd",
    "vy": "v_lat",
}
COLUMN_FLAGS = [flag for role, name in NAMES.items() for flag in ("--column", role, name)]
GRID_FLAGS = ["--d-lat", "20", "200", "10", "--d-long", "5", "60", "5"]


def _write(path, t, experiment) -> str:
    arrays = [t] + [getattr(experiment, role) for role in list(NAMES)[1:]]
    table = np.column_stack([*arrays, np.arange(len(t))])
    header = ",".join([*NAMES.values(), "sequence"])
    np.savetxt(path, table, delimiter=",", header=header, comments="", fmt="%.10g")
    return str(path)


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, str]:
    """A simulated 1 kHz run as CSV with clean and with Gazebo-like stamps."""
    # 2 s of steady cornering (2001 samples) keep the sampler cheap.
    experiment = simulate_experiment(
        ROBOT.replace(rate=1000.0), 110, 30, Series(v=0.4, w=0.52, duration=7.0), rng=11
    ).window(2.5, 4.5)
    folder = tmp_path_factory.mktemp("stamps")
    stamps, _ = gazebo_stamps(len(experiment.t), np.random.default_rng(3))
    stamps += experiment.t[0]
    for kind in ("clean", "jittered"):
        (folder / kind).mkdir()
    # The same file name: the experiments' names (the stems) are equal too.
    return {
        "clean": _write(folder / "clean" / "run.csv", experiment.t, experiment),
        "jittered": _write(folder / "jittered" / "run.csv", stamps, experiment),
    }


@pytest.fixture(scope="module")
def kilohertz_robot(tmp_path_factory) -> list[str]:
    """``--robot`` flags of the Jackal profile at the runs' 1 kHz (the CLI checks the rate)."""
    text = default_profile_path().read_text()
    assert "rate = 72.0" in text
    path = tmp_path_factory.mktemp("profile") / "jackal_1khz.toml"
    path.write_text(text.replace("rate = 72.0", "rate = 1000.0"))
    return ["--robot", str(path)]


def test_jittered_csv_reads_as_the_clean_one(runs):
    clean = read_csv(runs["clean"], columns=NAMES)
    jittered = read_csv(runs["jittered"], columns=NAMES)
    for role in NAMES:
        np.testing.assert_array_equal(getattr(jittered, role), getattr(clean, role))
    assert clean.provenance["repairs"] == []
    assert clean.provenance["columns"] == NAMES
    [repair] = jittered.provenance["repairs"]
    assert "jittered around a uniform 1000 Hz clock" in repair
    assert jittered.provenance["time_base"]["jitter"]["repeated"] > 0.1 * len(clean.t)


def test_grid_on_jittered_stamps_matches_clean_stamps(runs, kilohertz_robot, capsys):
    # The simulation grid (thesis ch. 5): its argmin on this grid is interior.
    payloads = {}
    for kind, path in runs.items():
        flags = [*COLUMN_FLAGS, *GRID_FLAGS, *kilohertz_robot, "--method", "simulation", "--json"]
        assert main(["grid", path, *flags]) == 0
        payloads[kind] = json.loads(capsys.readouterr().out)
    assert payloads["jittered"] == payloads["clean"]
    assert 20 < payloads["clean"]["d_lat"] < 200 and 5 < payloads["clean"]["d_long"] < 60
    argmins = [
        grid_search(
            [read_csv(path, columns=NAMES)],
            ROBOT,
            damping_grid(20, 200, 10),
            damping_grid(5, 60, 5),
            method="simulation",
        ).argmin()
        for path in runs.values()
    ]
    assert argmins[0] == argmins[1]
    assert argmins[0][:2] == (payloads["clean"]["d_lat"], payloads["clean"]["d_long"])


def test_sample_on_jittered_stamps_matches_clean_stamps(runs, kilohertz_robot, tmp_path, capsys):
    # The stamps are restored exactly to k x 1 ms, so the data and, with the
    # same seed, the chain are identical: equality, not a tolerance. White
    # noise keeps it cheap (a Gaussian kernel at 1 kHz spans up to 3000 taps).
    quick = ["--max-steps", "60", "--seed", "3", "--no-progress", "--json"]
    quick += ["--channels", "yaw", "--family", "white", *kilohertz_robot]
    payloads = {}
    for kind, path in runs.items():
        out = tmp_path / f"{kind}.nc"
        assert main(["sample", path, "--out", str(out), *COLUMN_FLAGS, *quick]) == 0
        payloads[kind] = json.loads(capsys.readouterr().out)
    assert payloads["jittered"] == payloads["clean"]
    posterior = load_posterior(tmp_path / "jittered.nc")
    [stored] = json.loads(posterior.posterior.attrs["experiments"])
    assert "jittered around a uniform 1000 Hz clock" in stored["provenance"]["repairs"][0]
    assert stored["provenance"]["time_base"]["clock"] == ONE_PER_TICK

    settings = SamplerSettings(max_steps=60)
    chains = []
    for path in runs.values():
        experiments = [read_csv(path, columns=NAMES)]
        likelihood = ResidualLikelihood(experiments, ROBOT, family="white", channels=("yaw",))
        with pytest.warns(UserWarning, match="NOT CONVERGED"):
            chains.append(sample_posterior(likelihood, settings, seed=3).posterior["d_lat"])
    np.testing.assert_array_equal(chains[0].values, chains[1].values)


# --------------------------------------------------------------------------- time base vs profile


def test_a_plausible_rate_other_than_the_profiles_is_accepted_and_said(
    runs, kilohertz_robot, capsys
):
    # Issue 24, item 13: the 1 kHz run under the 72 Hz Jackal profile was
    # refused until --rate 1000. It is a robot's rate: accepted, and said.
    with pytest.warns(UserWarning, match=r"run\.csv: sampled at 1000 Hz, not at the profile's 72"):
        assert load_experiment(runs["clean"], columns=NAMES, robot=ROBOT).dt == 0.001
    with warnings.catch_warnings():
        warnings.simplefilter("default")  # as on a user's terminal: pytest makes them errors
        assert main(["grid", runs["clean"], *COLUMN_FLAGS, *GRID_FLAGS]) == 0
    # (a grid minimum on the grid's edge would warn too: that warning is not the rate's)
    [line] = [line for line in capsys.readouterr().err.splitlines() if "sampled at" in line]
    assert "WARNING" in line and "sampled at 1000 Hz" in line and "--rate 1000" in line
    for flags in (["--rate", "1000"], kilohertz_robot):  # meant: nothing to say of the rate
        assert main(["grid", runs["clean"], *COLUMN_FLAGS, *GRID_FLAGS, *flags]) == 0
        assert "sampled at" not in capsys.readouterr().err


@pytest.mark.parametrize(
    ("unit", "scale", "offset"),
    [("milliseconds", 1e3, 0.0), ("nanoseconds", 1e9, 1.7e18)],  # ns: since the epoch
)
def test_time_in_milliseconds_or_nanoseconds_is_refused(tmp_path, capsys, unit, scale, offset):
    experiment = simulate_experiment(ROBOT, 110, 30, Series(v=0.4, w=0.52, duration=7.0), rng=1)
    seconds = write_csv(experiment, tmp_path / "seconds.csv")
    assert load_experiment(seconds, robot=ROBOT).dt == pytest.approx(1 / 72)
    lines = seconds.read_text().splitlines()
    rows = [line.split(",") for line in lines[1:]]
    scaled = [f"{float(row[0]) * scale + offset:.17g},{','.join(row[1:])}" for row in rows]
    path = tmp_path / f"{unit}.csv"
    path.write_text("\n".join([lines[0], *scaled]) + "\n")
    with pytest.raises(DataError, match=rf"{unit}\.csv: t: sample time .* looks like {unit}"):
        load_experiment(path, robot=ROBOT)
    assert main(["residuals", str(path)]) == 2
    err = capsys.readouterr().err
    assert "disagrees with the profile's rate 72 Hz" in err and unit in err, err


def test_a_bool_is_not_a_sample_time_or_a_rate(tmp_path):
    # float(True) is 1.0: dt=True read as 1 s would pass silently. Each user of
    # positive_number refuses it (numpy's bool too), naming the option.
    from bayes_jackal.likelihood.series_likelihood import SeriesLikelihood
    from bayes_jackal.noise.series import read_noise_series
    from bayes_jackal.posterior.series_statistics import spectrum
    from bayes_jackal.thesis.acf_fit import thesis_fit

    values = np.random.default_rng(1).standard_normal(64)
    for check in (
        lambda dt: spectrum(values, dt),
        lambda dt: thesis_fit(values, dt),
        lambda dt: SeriesLikelihood(values=values, dt=dt, family="white"),
    ):
        for bad in (True, np.True_):
            with pytest.raises(InputError, match=r"dt: .*must be a positive number of s, got"):
                check(bad)
    path = tmp_path / "gyro.csv"
    np.savetxt(path, values, header="gyro", comments="")
    with pytest.raises(InputError, match=r"rate: must be a positive number of Hz, got True"):
        read_noise_series(path, rate=True)
