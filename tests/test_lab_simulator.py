"""Checks of tests/lab_simulator.py, the independent simulator of lab logs.

The truth is checked against this file's own closed forms: A, B from
models/*.toml, the zero-order hold by scipy's matrix exponential, the
residual's variance by quadrature of the Gaussian autocorrelation, the
steady states of eq. 4-32. The logs are read back with the csv module and
rosbags alone. Tolerances are in sds of the estimator (Z of them) for the
run's length and the noise's correlation; every run is seeded, so the
checks are deterministic and Z says how unlikely a failure is.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
from lab_simulator import (
    DRIVE_COLUMNS,
    DRIVE_LIMITS,
    POSE_PRESETS,
    ROBOTS,
    SPARSE_ROLES,
    SpeedLaw,
    drive_manoeuvre,
    figure_eight,
    simulate,
    spot_rotation,
    step_sequence,
    thesis_circle,
    truncate_bag,
    write_drive_run,
    write_drive_table,
    write_lab_bag,
    write_sparse_csv,
)
from mocap_simulator import write_mocap_bag
from rosbags.highlevel import AnyReader

#: Allowed departures of a statistic from its target, in sds of its estimator.
Z = 4.0
#: Pose dropouts of the bag [s of run time]: (start, length).
DROPOUTS = [(10.0, 3.0), (30.0, 2.5)]


@pytest.fixture(scope="module")
def drive(tmp_path_factory) -> dict:
    """DRIVE-like Husky tables: steps (held and sparse ICP), speed-dependent steps, circles."""
    folder = tmp_path_factory.mktemp("drive")
    runs = {
        "steps": write_drive_run(folder / "steps.csv", rng=2024),
        "sparse": write_drive_run(folder / "sparse.csv", icp_layout="sparse", rng=2024),
        "speed": write_drive_run(folder / "speed.csv", speed_dependent=True, rng=7),
        "circles": write_drive_run(folder / "circles.csv", kind="circles", rng=8),
        "speed-circles": write_drive_run(
            folder / "speed_circles.csv", kind="circles", speed_dependent=True, rng=9
        ),
    }
    return runs


@pytest.fixture(scope="module")
def lab(tmp_path_factory) -> dict:
    """A Jackal step sequence at 72 Hz, written as a bag with dropouts and as a sparse CSV."""
    folder = tmp_path_factory.mktemp("lab")
    sim = simulate(step_sequence(3, 8), rate=72.0, rng=4)
    bag = write_lab_bag(folder / "steps.bag", sim, pose_rate=120.0, pose_dropouts=DROPOUTS, rng=5)
    table = write_sparse_csv(folder / "steps.csv", sim, rng=6)
    return {"sim": sim, "bag": bag, "csv": table}


def read_table(path: Path) -> tuple[list[str], list[list[str]]]:
    with open(path, newline="") as stream:
        header, *rows = list(csv.reader(stream))
    return header, rows


def read_topics(path: Path) -> dict[str, list]:
    """(Header stamp [s], or receive time without a header; message) per topic, in order."""
    topics: dict[str, list] = {}
    with AnyReader([path]) as reader:
        for connection, received, raw in reader.messages():
            message = reader.deserialize(raw, connection.msgtype)
            header = getattr(message, "header", None)
            ns = received if header is None else header.stamp.sec * 10**9 + header.stamp.nanosec
            topics.setdefault(connection.topic, []).append((ns * 1e-9, message))
    return topics


def continuous(robot: dict, d_lat: float, d_long: float) -> tuple[np.ndarray, np.ndarray]:
    """A and B of eq. 4-32 from the profile (not from the simulators)."""
    body = robot["body"]
    m, inertia, r = body["mass"], body["yaw_inertia"], body["wheel_radius"]
    a, b = body["half_wheelbase"], body["half_track"]
    A = np.diag([-4 * d_long / m, -4 * d_lat / m, -4 * (b**2 * d_long + a**2 * d_lat) / inertia])
    B = 2 * d_long * r * np.array([[1 / m, 1 / m], [0, 0], [b / inertia, -b / inertia]])
    return A, B


def zero_order_hold(A: np.ndarray, B: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    block = np.zeros((5, 5))
    block[:3, :3], block[:3, 3:] = A, B
    exponential = scipy.linalg.expm(block * dt)
    return exponential[:3, :3], exponential[:3, 3:]


def unit_variance(pole: float, sigma_h: float, dt: float) -> float:
    """Var of int_0^dt e^{a (dt - s)} xi(s) ds for xi of unit sd, ACF exp(-tau^2 / (4 sigma_h^2)).

    The double integral by 64-node Gauss-Legendre quadrature: the integrand is
    smooth on the scale sqrt(2) sigma_h >= dt, so it is exact to rounding.
    """
    nodes, weights = np.polynomial.legendre.leggauss(64)
    s, weights = dt * (nodes + 1) / 2, weights * dt / 2
    f = weights * np.exp(pole * (dt - s))
    return float(f @ np.exp(-((s[:, None] - s) ** 2) / (4 * sigma_h**2)) @ f)


def residuals(run) -> tuple[np.ndarray, np.ndarray]:
    """w[k] of the held steps with each step's own (Ad, Bd), and the step's segment."""
    robot, dt = ROBOTS[run.truth["robot"]], 1 / run.truth["rate"]
    steps = np.flatnonzero(run.held)
    out = np.empty((len(steps), 3))
    for i, k in enumerate(steps):
        segment = run.segment[k]
        A, B = continuous(robot, run.segments.d_lat[segment], run.segments.d_long[segment])
        Ad, Bd = zero_order_hold(A, B, dt)
        out[i] = run.states[k + 1] - Ad @ run.states[k] - Bd @ run.inputs[k]
    return out, run.segment[steps]


def spread(sigma_h: float, rate: float, n: int) -> float:
    """sd(s_hat) / s of a sample sd of n Gaussian residuals with w's autocorrelation.

    sqrt(sum rho^2 / (2 n)), rho the force's Gaussian ACF at the model's lags:
    w averages the force over one step, which widens its ACF by dt^2 / 6 in
    variance (2 % at DRIVE's 20 Hz and 0.1 s), negligible here.
    """
    lags = np.arange(-400, 401) / rate
    return math.sqrt(np.sum(np.exp(-(lags**2) / (4 * sigma_h**2)) ** 2) / (2 * n))


@pytest.mark.parametrize("name", ["steps", "circles"])
def test_the_residual_sd_at_the_model_clock_is_sigma_c(drive, name):
    run = drive[name]
    w, _ = residuals(run)
    # The realised sd in the truth is this one (from the simulator's closed forms).
    realised = w.std(axis=0)
    np.testing.assert_allclose(realised, list(run.truth["sigma_c_realised"].values()), rtol=1e-8)
    # 40 steps of 6 s at 20 Hz: N = 4800 residuals, sum rho^2 = 5.0, 2.3 % per channel.
    target = np.array(list(run.truth["sigma_c"].values()))
    sd = spread(run.truth["sigma_h"], run.truth["rate"], len(w))
    assert np.all(np.abs(realised / target - 1) < Z * sd), (realised / target - 1, sd)
    # The held steps are all but the ramps: all of a step sequence's steps.
    assert run.held.all() if name == "steps" else run.held.mean() > 0.97


def test_the_force_scale_matches_the_closed_form(drive, lab):
    for run in (drive["steps"], drive["speed"], lab["bag"]):
        truth, robot = run.truth, ROBOTS[run.truth["robot"]]
        force = np.array(list(truth["force_sd"].values()))
        A, _ = continuous(robot, truth["d_lat"], truth["d_long"])
        dt = 1 / truth["rate"]
        closed = force * np.sqrt([unit_variance(a, truth["sigma_h"], dt) for a in np.diag(A)])
        # The simulator holds the force over each fine step h: its residual's
        # variance departs from the smooth force's by O((h / sigma_h)^2), 2e-4
        # at 72 Hz and 47 ms, 6e-4 at 20 Hz and 0.1 s; 0.2 % allowed on the sd.
        np.testing.assert_allclose(closed, list(truth["sigma_c"].values()), rtol=2e-3)


def test_a_long_step_settles_at_the_models_steady_state():
    manoeuvre = step_sequence(11, 4, step_duration=20.0)
    sim = simulate(manoeuvre, rate=72.0, rng=12)
    truth, robot = sim.truth, ROBOTS["jackal"]
    A, B = continuous(robot, truth["d_lat"], truth["d_long"])
    r_w = robot["body"]["wheel_radius"]
    t, states, inputs = sim.t[sim.ticks], sim.x[sim.ticks], sim.u[sim.ticks]
    force = np.array(list(truth["force_sd"].values()))
    for start, end in zip(manoeuvre.edges[1:-2], manoeuvre.edges[2:-1], strict=True):
        # From 2 s in: >= 14 time constants (the slowest is 0.14 s), e^-14 of the jump left.
        inside = (t >= start + 2.0) & (t < end - 1e-6)  # the tick at the edge is the next's
        omega_r, omega_l = inputs[inside][0]
        assert np.all(inputs[inside] == [omega_r, omega_l])
        expected = [r_w * (omega_r + omega_l) / 2, 0.0, B[2, 0] / -A[2, 2] * (omega_r - omega_l)]
        # sd of a mean over T of a channel's noise: the force's spectrum at
        # zero, force^2 2 sqrt(pi) sigma_h, over a^2 T: ~1e-3 m/s, 3e-3 rad/s.
        span = end - start - 2.0
        sd = force / np.abs(np.diag(A)) * np.sqrt(2 * np.sqrt(np.pi) * truth["sigma_h"] / span)
        mean = states[inside].mean(axis=0)
        assert np.all(np.abs(mean - expected) < Z * sd), (mean, expected, sd)


def runs_of(column: list[str]) -> list[int]:
    """Lengths of the runs of equal consecutive cells."""
    edges = [0, *[i for i in range(1, len(column)) if column[i] != column[i - 1]], len(column)]
    return list(np.diff(edges))


def test_held_columns_repeat_at_their_sensors_rate(drive):
    run = drive["steps"]
    header, rows = read_table(run.path)
    assert tuple(header) == DRIVE_COLUMNS
    assert all(all(cells) for cells in rows)  # the held layout fills every cell
    for names, rate, messages in [
        (("meas_left_vel", "meas_right_vel"), 4.0, run.wheel_t),
        (("icp_x", "icp_y", "icp_yaw"), 5.0, run.pose_t),
    ]:
        for name in names:
            lengths = runs_of([row[header.index(name)] for row in rows])
            # One run per message (noisy values never repeat by chance): 20 /
            # rate rows each, one more or less where 1 ms of jitter on both
            # clocks, or a missing row, moves a message across a tick.
            assert len(lengths) == len(messages)
            nominal = round(20.0 / rate)
            assert set(lengths[1:-1]) <= {nominal - 1, nominal, nominal + 1}, set(lengths)
            # The mean is the period: the messages' clock is exact, and two
            # missing rows in ~1000 runs move it by 0.002.
            assert abs(np.mean(lengths[1:-1]) - nominal) < 0.01
    # Each encoder value is the truth at the encoder's instant + 0.05 rad/s.
    index = [header.index("meas_right_vel"), header.index("meas_left_vel")]
    first = np.r_[0, np.cumsum(runs_of([row[index[0]] for row in rows]))[:-1]]
    values = np.array([[float(rows[i][j]) for j in index] for i in first])
    error = (values - run.wheels).ravel()
    assert abs(error.std() / run.truth["wheel_sd"] - 1) < Z / np.sqrt(2 * len(error))


def test_commands_and_steps_are_held_per_step(drive):
    run = drive["steps"]
    header, rows = read_table(run.path)
    table = {name: [row[header.index(name)] for row in rows] for name in header}
    steps = np.array(table["calib_step"], int)
    assert steps[0] == -1 and steps[-1] == -1 and set(steps) == {-1, *range(40)}
    kept = np.setdiff1d(np.arange(len(run.t)), run.truth["missing_ticks"])
    np.testing.assert_array_equal(steps, run.segments.step[run.segment[kept]])
    # 2 s rest (40 rows), 40 x 6 s at 20 Hz (120 rows each), 2 s rest and the
    # last tick (41 rows), less the two missing rows.
    counts = np.bincount(steps + 1)
    assert counts[0] in (79, 80, 81) and set(counts[1:]) <= {119, 120}
    assert counts.sum() == 4881 - 2
    for name in ("cmd_left_vel", "cmd_right_vel"):
        assert len(runs_of(table[name])) <= 42  # changes only at the steps' edges
    assert len(run.truth["missing_ticks"]) == 2 and len(rows) == len(run.t) - 2
    # Stamps: the ticks with 1 ms of jitter, less the first row's (time zero).
    deviation = np.array(table["ros_time"], float) - run.t[kept]
    assert abs(deviation.std() / 1e-3 - 1) < Z / np.sqrt(2 * len(deviation))
    assert abs(deviation.mean()) < Z * 1e-3
    assert all(len(cell.split(".")[1]) == 6 for cell in table["ros_time"])


def test_sparse_rows_hold_exactly_their_cells(drive, lab):
    run = drive["sparse"]
    header, rows = read_table(run.path)
    icp = {header.index(name) for name in ("icp_x", "icp_y", "icp_yaw")}
    filled = [{i for i, cell in enumerate(row) if cell} for row in rows]
    pose_rows = [cells for cells in filled if cells == {0, *icp}]
    logger_rows = [cells for cells in filled if cells == set(range(len(header))) - icp]
    assert len(pose_rows) + len(logger_rows) == len(rows)
    assert len(pose_rows) == len(run.pose_t) and len(logger_rows) == len(run.t) - 2
    times = np.array([float(row[0]) for row in rows])
    assert np.all(np.diff(times) > 0)
    # Same seed, same run: the logger rows are the held table's but for the ICP cells.
    _, held = read_table(drive["steps"].path)
    rest = [i for i in range(len(header)) if i not in icp]
    logger = [row for row, cells in zip(rows, filled, strict=True) if cells != {0, *icp}]
    assert [[r[i] for i in rest] for r in logger] == [[r[i] for i in rest] for r in held]

    table = lab["csv"]
    header, rows = read_table(table.path)
    assert header == list(SPARSE_ROLES.values())
    imu_cells, pose_cells = {0, 1, 2, 3}, {0, 4, 5, 6}
    filled = [{i for i, cell in enumerate(row) if cell} for row in rows]
    assert all(cells in (imu_cells, pose_cells) for cells in filled)
    imu = np.array(
        [
            [float(row[i]) for i in (0, 1)]
            for row, c in zip(rows, filled, strict=True)
            if c == imu_cells
        ]
    )
    assert len(imu) == len(table.t) - 2
    kept = np.setdiff1d(np.arange(len(table.t)), table.truth["missing_ticks"])
    # IMU stamps: 0.1 ms of jitter on each and on the first (time zero): within 1 ms.
    assert np.max(np.abs(imu[:, 0] - table.t[kept])) < 1e-3
    assert np.all(np.diff([float(row[0]) for row in rows]) > 0)
    assert sum(c == pose_cells for c in filled) == len(table.pose_t)


def test_pose_noise_of_the_tables(drive, lab):
    cases = [
        (drive["sparse"], ("icp_x", "icp_y", "icp_yaw"), "icp_sd", "icp_heading_sd"),
        (lab["csv"], ("pos_x", "pos_y", "yaw"), "pose_sd", "heading_sd"),
    ]
    for run, names, position_sd, heading_sd in cases:
        header, rows = read_table(run.path)
        index = [header.index(name) for name in names]
        poses = np.array([[float(row[i]) for i in index] for row in rows if row[index[0]]])
        error = poses - run.poses
        error[:, 2] = np.angle(np.exp(1j * error[:, 2]))  # the written heading is wrapped
        assert np.all(np.abs(poses[:, 2]) <= np.pi)
        # White noise: sd(s_hat) / s = 1 / sqrt(2 n).
        for values, key in ((error[:, :2].ravel(), position_sd), (error[:, 2], heading_sd)):
            sd = run.truth[key]
            assert abs(values.std() / sd - 1) < Z / np.sqrt(2 * len(values)), (key, values.std())


def test_pose_dropouts_leave_the_other_topics_going(lab):
    run = lab["bag"]
    topics = read_topics(run.path)
    origin = topics["/imu/data"][0][0]
    pose = np.array(sorted({s for s, _ in topics["/mocap_node/Jackal/pose"]})) - origin
    np.testing.assert_allclose(pose, run.pose_t, atol=5e-4)  # 0.05 + 0.1 ms of jitter
    assert run.truth["pose_in_dropouts"] == pytest.approx(120 * sum(d for _, d in DROPOUTS), abs=2)
    for start, length in DROPOUTS:
        # No pose inside (the log's zero is the run's within 0.5 ms); the
        # gap is the window, to a pose period (8.3 ms) at each side and 2
        # more if a pose lost in transport (0.2 %) borders it.
        assert not np.any((pose > start + 1e-3) & (pose < start + length - 1e-3))
        before, after = pose[pose < start + 1e-3].max(), pose[pose > start + length - 1e-3].min()
        assert length - 1e-3 < after - before < length + 4 / 120
        # The other clocks run on: rate x length messages, one more or less
        # by the clock's phase (the command's receive times are 1-3 ms late).
        for topic, rate in [("/imu/data", 72), ("/joint_states", 50), ("/cmd_vel", 20)]:
            stamps = np.array([s for s, _ in topics[topic]]) - origin
            inside = np.sum((stamps >= start) & (stamps < start + length))
            assert abs(inside - rate * length) <= 1, (topic, inside)
    # Dropouts are unpublished poses: no gap in seq for them, only the transport losses.
    seqs = {m.header.seq for _, m in topics["/mocap_node/Jackal/pose"]}
    assert max(seqs) + 1 - len(seqs) == run.truth["pose_dropped"]


def test_speed_dependent_damping_follows_its_law(drive):
    run = drive["speed"]
    segments, truth = run.segments, run.truth
    slope = math.log(1.5) / DRIVE_LIMITS["v_max"]
    assert truth["slope"] == {"d_lat": pytest.approx(slope), "d_long": pytest.approx(slope)}
    assert truth["v_ref"] == 0.5
    for key in ("d_lat", "d_long"):
        law = truth[key] * np.exp(slope * (np.abs(segments.v) - truth["v_ref"]))
        np.testing.assert_allclose(getattr(segments, key), law, rtol=1e-12)
    # 50 % higher at the top speed than at rest.
    ratio = SpeedLaw.from_ratio(1.5, 0.0, 1.0).damping(306.0, 84.0, np.array([1.0, 0.0]))
    np.testing.assert_allclose(ratio[0] / ratio[1], 1.5)
    assert np.ptp(segments.d_lat) > 0.3 * truth["d_lat"]  # the steps span the speeds
    # The force is the reference's in every step: each step's residual sd
    # is the closed form at its damping (0.2 % as in the force-scale test).
    robot, dt = ROBOTS["husky"], 1 / truth["rate"]
    force = np.array(list(truth["force_sd"].values()))
    for i in range(len(segments.v)):
        A, _ = continuous(robot, segments.d_lat[i], segments.d_long[i])
        closed = force * np.sqrt([unit_variance(a, truth["sigma_h"], dt) for a in np.diag(A)])
        np.testing.assert_allclose(segments.sigma_c[i], closed, rtol=2e-3)
    # Rescaled to the reference damping, the realised residual sd is sigma_c
    # (4800 residuals: 2.3 % per channel, as for constant damping).
    w, segment = residuals(run)
    scaled = w / segments.sigma_c[segment] * list(truth["sigma_c"].values())
    realised = scaled.std(axis=0)
    np.testing.assert_allclose(realised, list(truth["sigma_c_realised"].values()), rtol=1e-8)
    sd = spread(truth["sigma_h"], truth["rate"], len(w))
    assert np.all(np.abs(realised / list(truth["sigma_c"].values()) - 1) < Z * sd)


def test_at_the_reference_speed_the_residual_sd_is_sigma_c(drive):
    """Steady circles with speed-dependent damping, one of them at v_ref = 0.5 m/s."""
    run = drive["speed-circles"]
    segments, truth = run.segments, run.truth
    (at_ref,) = np.flatnonzero(np.abs(segments.v) == truth["v_ref"])
    assert (segments.d_lat[at_ref], segments.d_long[at_ref]) == (306.0, 84.0)
    assert np.ptp(segments.d_lat[segments.step >= 0]) > 0.3 * 306.0
    w, segment = residuals(run)
    realised = w[segment == at_ref].std(axis=0)
    # Not rescaled: the circle's 60 s less its 1 s ramp at 20 Hz, N = 1180
    # residuals, sd 4.6 % per channel; the other circles' sds differ by 2-12 %.
    sd = spread(truth["sigma_h"], truth["rate"], np.sum(segment == at_ref))
    assert np.all(np.abs(realised / list(truth["sigma_c"].values()) - 1) < Z * sd), realised


def test_a_truncated_bag_is_cut_and_does_not_open(lab, tmp_path):
    original = lab["bag"].path
    cut = truncate_bag(original, 0.6, out=tmp_path / "cut.bag")
    assert cut.stat().st_size == int(0.6 * original.stat().st_size)
    assert cut.read_bytes() == original.read_bytes()[: cut.stat().st_size]
    with pytest.raises(Exception, match=r"(?i)index|header"):
        with AnyReader([cut]) as reader:
            sum(1 for _ in reader.messages())
    with AnyReader([original]) as reader:  # the original is kept whole
        assert reader.message_count > 0


def test_the_manoeuvres_shapes():
    t = np.arange(0.0, 60.0, 0.01)
    steps = step_sequence(1, 40)
    command = steps.command(t)
    inside = (t >= 2.0) & (t < 8.0)
    assert np.all(command[inside] == steps.levels[1]) and np.all(command[t < 2.0] == 0)
    assert np.all(np.abs(steps.levels) <= [1.0, 1.0]) and np.any(steps.levels[1:-1] == 0)
    assert steps.duration == 244.0 == drive_manoeuvre("circles").duration
    eight = figure_eight()
    hold = (t >= 2.0) & (t <= 42.0)
    np.testing.assert_allclose(eight.command(t)[hold, 0], 0.3)
    np.testing.assert_allclose(
        eight.command(t)[hold, 1], 0.6 * np.sin(2 * np.pi * (t[hold] - 1) / 20)
    )
    spot = spot_rotation(0.8, turn=5.0, repeats=2)
    turning = spot.command(t)
    assert np.all(turning[:, 0] == 0) and spot.duration == 29.0
    for k, sign in enumerate([1, -1, 1, -1]):
        middle = 1.0 + 7.0 * k + 0.5 + 2.5  # the middle of turn k
        assert turning[np.searchsorted(t, middle), 1] == pytest.approx(sign * 0.8)
    assert list(spot.step) == [-1, 0, -1, 1, -1, 2, -1, 3, -1]


def test_the_thesis_circle_is_mocap_simulators(tmp_path):
    """The piecewise integration of a constant damping is mocap_simulator's closed form."""
    run = write_mocap_bag(tmp_path / "v1.bag", pose_rate=10.0, rng=21)
    sim = simulate(thesis_circle(), rate=72.0, rng=21)
    np.testing.assert_allclose(sim.x[sim.ticks], run.states, rtol=0, atol=1e-12)


def test_the_same_seed_writes_the_same_logs(tmp_path):
    manoeuvre = spot_rotation()
    first, second, other = (
        simulate(manoeuvre, robot="husky", rate=50.0, rng=seed) for seed in (3, 3, 4)
    )
    np.testing.assert_array_equal(first.x, second.x)
    assert not np.allclose(first.x, other.x)
    for name, write in [
        ("bag", lambda path, sim, rng: write_lab_bag(path, sim, **POSE_PRESETS["slow"], rng=rng)),
        ("csv", lambda path, sim, rng: write_sparse_csv(path, sim, rng=rng)),
    ]:
        paths = [tmp_path / f"{name}{i}" for i in range(3)]
        for path, sim, seed in zip(paths, (first, second, first), (5, 5, 6), strict=True):
            write(path, sim, seed)
        assert paths[0].read_bytes() == paths[1].read_bytes() != paths[2].read_bytes()
    sims = [simulate(step_sequence(seed, 3), robot="husky", rate=20.0, rng=1) for seed in (8, 8)]
    paths = [tmp_path / f"drive{i}.csv" for i in range(2)]
    for path, sim in zip(paths, sims, strict=True):
        write_drive_table(path, sim, epoch=1.7e9, rng=2)
    assert paths[0].read_bytes() == paths[1].read_bytes()
    # An epoch-like offset keeps the microseconds of the run-relative stamps:
    # both are rounded to 1 us (0.5 us each) and a double near 1.7e9 resolves 0.24 us.
    relative = write_drive_table(tmp_path / "relative.csv", sims[0], rng=2).path
    stamps = [np.array([float(r[0]) for r in read_table(p)[1]]) for p in (paths[0], relative)]
    assert np.max(np.abs(stamps[0] - 1.7e9 - stamps[1])) < 1.3e-6
