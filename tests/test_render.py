"""Rendering (MuJoCo offscreen, EGL): the underwater look of every frame and what is drawn in it."""

import numpy as np
import pytest

from marinejax.render import FOG_END_M, FOG_START_M, WATER_RGBA, FrameRenderer, render_frames
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
