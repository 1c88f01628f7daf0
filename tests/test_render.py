"""Rendering (MuJoCo offscreen, EGL): the underwater look of every frame and what is drawn in it."""

import numpy as np
import pytest

from marinejax.render import (ECHO_RGB, FAN_RGB, FOG_END_M, FOG_START_M, WATER_RGBA, FrameRenderer, SonarTrace, render_frames,
                              sonar_display)
from marinejax.vehicle import load_vehicle

LEVEL = (np.array([0.0, 0.0, -2.0]), np.array([1.0, 0.0, 0.0, 0.0]))  # the vehicle 2 m deep, heading +x


@pytest.fixture(scope="module")
def vehicle():
    return load_vehicle("remus100")


@pytest.fixture(scope="module")
def renderer(vehicle):
    r = FrameRenderer(vehicle.mj_model, width=160, height=120, qpos_adr=vehicle.sys.qpos_adr)
    yield r
    r.close()


def test_far_water_takes_the_colour_of_the_fog_and_the_caller_model_is_untouched(vehicle, renderer):
    extent = renderer.model.stat.extent
    assert renderer.model.vis.map.fogstart * extent == pytest.approx(FOG_START_M)
    assert renderer.model.vis.map.fogend * extent == pytest.approx(FOG_END_M)
    assert not renderer.model.light_castshadow.any()  # shadow maps over the 400 m seabed speckled it
    assert vehicle.mj_model.light_castshadow.any() and vehicle.mj_model.vis.map.fogend != renderer.model.vis.map.fogend
    frame = renderer.frame(*LEVEL, target=np.array([3.0, 0.0, -2.0]))
    water = np.round(255 * np.asarray(WATER_RGBA[:3]))
    # the top row looks far into open water (the sky box beyond the fog): the water's colour
    np.testing.assert_allclose(frame[0].reshape(-1, 3).mean(0), water, atol=3)
    # the seabed 8 m below the vehicle, nearer than the fog's end, is not
    assert np.abs(frame[-1].reshape(-1, 3).mean(0) - water).max() > 15


def test_the_trail_and_the_target_are_drawn(renderer):
    plain = renderer.frame(*LEVEL, target=np.array([0.0, 0.0, -20.0]))  # the target out of sight
    trail = np.stack([np.linspace(-3.0, -0.5, 12), np.zeros(12), np.full(12, -2.0)], 1)
    with_trail = renderer.frame(*LEVEL, target=np.array([0.0, 0.0, -20.0]), trail=trail)
    with_target = renderer.frame(*LEVEL, target=np.array([0.5, -1.0, -1.5]))
    changed = lambda a: int(np.any(a != plain, axis=-1).sum())  # noqa: E731
    assert changed(with_trail) > 5 and changed(with_target) > 5  # a few pixels at 160 x 120
    # the trail is yellow: the pixels it changed are more red than blue
    mask = np.any(with_trail != plain, axis=-1)
    assert with_trail[mask][:, 0].mean() > with_trail[mask][:, 2].mean()


def test_an_episode_draws_its_past_as_the_trail(vehicle, renderer):
    steps = 30
    position = np.stack([np.linspace(-3.0, 0.0, steps), np.zeros(steps), np.full(steps, -2.0)], 1)
    quaternion = np.tile([1.0, 0.0, 0.0, 0.0], (steps, 1))
    frames = render_frames(vehicle.mj_model, position, quaternion, position + [0.0, 0.0, -30.0], vehicle.sys.qpos_adr,
                           width=160, height=120)
    assert len(frames) == steps and frames[0].shape == (120, 160, 3)
    # the first frame has no past; the last one has its trail behind the vehicle
    bare = renderer.frame(position[-1], quaternion[-1], position[-1] + [0.0, 0.0, -30.0], position + [0.0, 0.0, -30.0])  # the same path
    assert np.any(frames[-1] != bare)


def _sonar_trace(steps, ranges, intensity=None):
    """A 32-beam sonar's trace: every step the same `ranges` (32,), m; max range 20 m."""
    from marinejax.plant.rays import fan, spread

    ranges = np.tile(np.asarray(ranges, float), (steps, 1))
    return SonarTrace(ranges=ranges, hit=ranges < 20.0, intensity=None if intensity is None else np.tile(intensity, (steps, 1)),
                      mount=np.array([0.25, 0.0, 0.0]), directions=fan(32, np.radians(130.0), 1, 0.0, np.radians(10.0))[:, 0],
                      azimuth=spread(32, np.radians(130.0)), max_range=20.0)


def test_the_sonar_display_draws_echoes_at_their_bearing_and_range():
    """Echoes at 10 m on the left half of the fan only (bearings > 0), the apex at the bottom centre:
    the echo arc 10 m up the display's centre line and 30° to the left, dim water before it, shadow
    behind it, nothing on the right half but the water and the range rings, black outside the fan; an intensity of
    0.3 draws the echo dimmer than full strength."""
    trace = _sonar_trace(1, np.where(np.arange(32) >= 16, 10.0, 20.0))
    size = 101
    image = sonar_display(trace.ranges[0], trace.hit[0], None, trace.azimuth, 20.0, size).astype(float) / 255
    scale = 20.0 / (size - 2.0)
    at = lambda r, deg: image[int(round(size - 1 - r * np.cos(np.radians(deg)) / scale)),  # noqa: E731
                              int(round(size / 2 - r * np.sin(np.radians(deg)) / scale))]
    np.testing.assert_allclose(at(10.0, 30.0), ECHO_RGB, atol=0.01)
    np.testing.assert_allclose(at(10.0, 60.0), ECHO_RGB, atol=0.01)
    np.testing.assert_allclose(at(7.0, 30.0), FAN_RGB, atol=0.01)  # the water before the echo
    np.testing.assert_allclose(at(13.0, 30.0), 0.4 * FAN_RGB, atol=0.01)  # its shadow
    np.testing.assert_allclose(at(11.0, -30.0), FAN_RGB, atol=0.01)  # the right half: no echo
    np.testing.assert_allclose(at(10.0, -30.0), FAN_RGB + 0.25, atol=0.01)  # a range ring (every 5 m)
    np.testing.assert_allclose(image[0, 0], 0.0)  # outside the fan: beyond its range
    np.testing.assert_allclose(at(10.0, 80.0), 0.0)  # and beyond its aperture (±65°)
    dim = sonar_display(trace.ranges[0], trace.hit[0], np.full(32, 0.3), trace.azimuth, 20.0, size).astype(float) / 255
    echo = (int(round(size - 1 - 10.0 * np.cos(np.radians(30.0)) / scale)), int(round(size / 2 - 10.0 * np.sin(np.radians(30.0)) / scale)))
    np.testing.assert_allclose(dim[echo], FAN_RGB + 0.3 * (ECHO_RGB - FAN_RGB), atol=0.01)


def test_an_episode_with_a_sonar_shows_its_beams_and_its_display_beside_the_chase_view(vehicle):
    steps = 2
    position = np.tile([0.0, 0.0, -2.0], (steps, 1))
    quaternion = np.tile([1.0, 0.0, 0.0, 0.0], (steps, 1))
    targets = position + [0.0, 0.0, -30.0]
    plain = render_frames(vehicle.mj_model, position, quaternion, targets, vehicle.sys.qpos_adr, width=160, height=120)
    trace = _sonar_trace(steps, np.full(32, 4.0))
    frames = render_frames(vehicle.mj_model, position, quaternion, targets, vehicle.sys.qpos_adr, width=160, height=120, sonar=trace)
    assert frames[0].shape == (120, 160 + 120, 3)
    chase = frames[-1][:, :160]
    changed = np.any(chase != plain[-1], axis=-1)
    assert changed.sum() > 20  # the fan's beams, 4 m ahead of the vehicle
    assert chase[changed][:, 0].mean() > chase[changed][:, 2].mean()  # echoes drawn yellow
    np.testing.assert_array_equal(frames[-1][:, 160:], sonar_display(trace.ranges[0], trace.hit[0], None, trace.azimuth, 20.0, 120))
