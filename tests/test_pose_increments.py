"""Poses on the IMU clock: the pose each sample takes, its noise, and the body increments.

Numbers and where they come from:

- a sample's pose averages the n poses it owns: n = floor(pose rate / IMU
  rate) for a clock of its own phase (5 at 360 Hz, 3 at 240 Hz, 1 at 120 Hz
  against 72 Hz), so white pose noise of sd s becomes s / sqrt(n) at each
  sample, independent from sample to sample. Over ~1,400 samples the sd's
  relative sampling error is 1 / sqrt(2 N) ~ 1.9 %, so it is checked within
  8 % (4 sd), and a lag-1 correlation within 0.11 (4 / sqrt(N));
- on a noise-free circle the moved poses are the true ones to the cube of
  the offset (< 1e-7 m here), and the body increments are the chord of
  each step, v dt (1 - (r dt)^2 / 24), along the heading.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from bayes_jackal._runtime.errors import DataError
from bayes_jackal.io.experiment import Experiment, read_netcdf, write_netcdf
from bayes_jackal.io.pose_increments import body_displacement, body_increments, tick_poses
from bayes_jackal.io.pose_track import PoseTrack

SPEED, TURN, RADIUS = 0.3, 0.4, 0.75  # v [m/s], r [rad/s], v / r [m]


def _circle(rate: float, sd: float, *, seconds: float = 20.0, seed: int = 1) -> Experiment:
    """A steady circle sampled at 72 Hz, its poses at ``rate`` with white noise of sd ``sd``."""
    rng = np.random.default_rng(seed)
    t = np.arange(round(seconds * 72) + 1) / 72
    s = np.arange(-3, round(seconds * rate) + 4) / rate + rng.uniform(0, 1 / rate)
    heading = TURN * s
    x = RADIUS * np.sin(heading) + sd * rng.standard_normal(len(s))
    y = RADIUS * (1 - np.cos(heading)) + sd * rng.standard_normal(len(s))
    return Experiment(
        t=t,
        yaw_rate=np.full(len(t), TURN),
        omega_r=np.full(len(t), 4.0),
        omega_l=np.full(len(t), 2.0),
        vx=np.full(len(t), SPEED),
        vy=np.zeros(len(t)),
        pose=PoseTrack(s, x, y, heading),
    )


@pytest.mark.parametrize(("rate", "samples"), [(360.0, 5), (240.0, 3), (120.0, 1)])
def test_each_sample_averages_the_poses_it_owns(rate, samples):
    truth, noisy = _circle(rate, 0.0), _circle(rate, 5e-4)
    exact, ticks = tick_poses(truth), tick_poses(noisy)
    assert (ticks.samples, ticks.borrowed) == (samples, 0)
    t = truth.t
    np.testing.assert_allclose(exact.x, RADIUS * np.sin(TURN * t), atol=1e-7)
    np.testing.assert_allclose(exact.heading, TURN * t, atol=1e-9)
    error = ticks.x - exact.x
    np.testing.assert_allclose(error.std(), 5e-4 / np.sqrt(samples), rtol=0.08)
    assert abs(np.corrcoef(error[1:], error[:-1])[0, 1]) < 0.11


def test_a_dropout_makes_its_samples_borrow_their_neighbours_poses():
    run = _circle(360.0, 0.0)
    pose = run.pose
    keep = np.ones(len(pose.t), bool)
    keep[1000:1003] = False  # 8 ms of missing poses
    holed = PoseTrack(pose.t[keep], pose.x[keep], pose.y[keep], pose.heading[keep])
    ticks = tick_poses(dataclasses.replace(run, pose=holed))
    assert ticks.samples == 5 and 1 <= ticks.borrowed <= 2
    np.testing.assert_allclose(ticks.x, RADIUS * np.sin(TURN * run.t), atol=1e-6)


def test_poses_that_do_not_cover_the_samples_are_refused():
    run = _circle(360.0, 0.0)
    pose = run.pose
    late = pose.t > 5.0
    short = PoseTrack(pose.t[late], pose.x[late], pose.y[late], pose.heading[late])
    with pytest.raises(DataError, match="no pose within one step"):
        tick_poses(dataclasses.replace(run, pose=short))


def test_the_body_increments_are_the_steps_chords_along_the_heading():
    ticks = tick_poses(_circle(360.0, 0.0))
    dt = 1 / 72
    chord = SPEED * dt * (1 - (TURN * dt) ** 2 / 24)
    # 1e-9 m inside; at the ends the smoother's rate errs by ~3e-4 m/s (its
    # fit is one-sided there), times offsets of up to 1.4 ms: 1e-7 m.
    for channel, expected in (("vx", chord), ("vy", 0.0)):
        increments = body_increments(ticks, channel)
        np.testing.assert_allclose(increments[5:-5], expected, rtol=0, atol=1e-9)
        np.testing.assert_allclose(increments, expected, rtol=0, atol=1e-7)
    travel = body_displacement(ticks, "vx")
    assert travel[0] == 0.0
    np.testing.assert_allclose(np.diff(travel), body_increments(ticks, "vx"))


def test_a_window_keeps_the_poses_around_its_samples_and_the_file_keeps_them(tmp_path):
    run = _circle(360.0, 5e-4)
    window = run.window(5.0, 10.0)
    assert window.pose.t[0] >= 5.0 - run.dt and window.pose.t[0] < 5.0
    assert window.pose.t[-1] <= 10.0 + run.dt and window.pose.t[-1] > 10.0
    assert tick_poses(window).samples == 5
    back = read_netcdf(write_netcdf(run, tmp_path / "circle.nc"))
    np.testing.assert_array_equal(back.pose.heading, run.pose.heading)
    assert back.measurement("vx") == "pose"


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"x": np.full(10, np.nan)}, "pose.x: nan at pose 0"),
        ({"y": np.full(10, 2e4)}, "pose.y: 20000 m at pose 0"),
        ({"t": np.zeros(10)}, "pose.t: pose stamps must increase"),
        ({"heading": np.zeros(9)}, "pose arrays must have one length"),
        ({"x": np.array(["a"] * 10)}, "pose.x: expected a 1-D array of numbers"),
    ],
)
def test_a_bad_pose_track_is_refused_naming_the_field(change, message):
    fields = {"t": np.arange(10.0), "x": np.zeros(10), "y": np.zeros(10), "heading": np.zeros(10)}
    with pytest.raises(DataError, match=message):
        PoseTrack(**(fields | change), source="run.bag")


def test_poses_need_their_derived_velocities_and_must_overlap_the_samples():
    run = _circle(360.0, 0.0)
    with pytest.raises(DataError, match="poses need the velocities derived from them"):
        dataclasses.replace(run, vx=None)
    pose = run.pose
    far = PoseTrack(pose.t + 100.0, pose.x, pose.y, pose.heading)
    with pytest.raises(DataError, match="do not overlap the samples"):
        dataclasses.replace(run, pose=far)


def test_poses_slower_than_the_samples_are_refused():
    # At 50 Hz against 72 Hz, 31 % of the samples own no pose: borrowing them
    # would share a pose's noise between neighbours, which the model's white
    # pose noise is not.
    with pytest.raises(DataError, match=r"own no pose within half a step: the poses \(50 Hz\)"):
        tick_poses(_circle(50.0, 0.0))


def test_an_experiments_tick_poses_are_moved_once_and_read_only():
    # The filters take them once per prior draw: kept for the experiment's
    # life, the same object, which no caller can change; a copy of the
    # experiment (another object) moves its poses anew, to the same values.
    run = _circle(360.0, 0.002)
    ticks = tick_poses(run)
    assert tick_poses(run) is ticks
    with pytest.raises(ValueError, match="read-only"):
        ticks.x[0] = 1.0
    again = tick_poses(dataclasses.replace(run))
    assert again is not ticks
    for name in ("x", "y", "heading"):
        np.testing.assert_array_equal(getattr(again, name), getattr(ticks, name))
