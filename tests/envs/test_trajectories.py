"""Reference paths: geometry, constant speed after the ramp, exact velocity, sampling, validation."""

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from marinejax.envs.trajectories import KINDS, TrajectoryConfig, TrajectoryParams, path_length, reference, sample_params

LEMNISCATE_CONSTANT = 2.622057554292119  # ϖ: one lap of the a = 1 lemniscate of Bernoulli is 2ϖ
RAMP = 2.0
TIMES = np.linspace(0.0, 40.0, 8001)  # s, one shape for every jitted call (compiled once per kind)
DT = 0.01  # s, central finite differences


def _params(kind, **overrides):
    """A fixed, non-trivial path: off-origin centre, clockwise, non-zero phase (and heading)."""
    values = dict(
        center=jnp.array([1.5, -0.7, -5.0]),
        size=jnp.float32(1.3),
        speed=jnp.float32(0.45),
        pitch=jnp.float32(0.5 if kind == "helix" else 0.0),
        direction=jnp.float32(-1.0),
        phase=jnp.float32(0.3),
        heading=jnp.float32(0.7 if kind == "lemniscate" else 0.0),
        ramp_time=jnp.float32(RAMP),
    )
    values.update({k: jnp.asarray(v, jnp.float32) for k, v in overrides.items()})
    return TrajectoryParams(**values)


@pytest.fixture(scope="module")
def ref():
    return jax.jit(reference, static_argnums=0)


@pytest.fixture(scope="module")
def sample():
    return jax.jit(sample_params, static_argnums=(0, 2))


@pytest.fixture(scope="module")
def sample_batch():
    """(kind, keys (B, 2), config) -> batched params, and their references at t = 1 s (vmap inside jit)."""

    def run(kind, keys, config):
        batch = jax.vmap(lambda k: sample_params(kind, k, config))(keys)
        return batch, jax.vmap(lambda q: reference(kind, q, 1.0))(batch)

    return jax.jit(run, static_argnums=(0, 2))


@pytest.fixture(scope="module")
def paths(ref):
    """kind -> (params, position, velocity, positions at t ± DT) over TIMES."""
    out = {}
    for kind in KINDS:
        p = _params(kind)
        pos, vel = ref(kind, p, jnp.asarray(TIMES + DT))  # shifted grids share the compiled function
        plus = np.asarray(pos)
        minus = np.asarray(ref(kind, p, jnp.asarray(TIMES - DT))[0])
        pos, vel = ref(kind, p, jnp.asarray(TIMES))
        out[kind] = (p, np.asarray(pos, np.float64), np.asarray(vel, np.float64), plus, minus)
    return out


@pytest.mark.parametrize("kind", ["circle", "helix"])
def test_circle_and_helix_radius_and_centre(paths, kind):
    p, pos, _, _, _ = paths[kind]
    c, r = np.asarray(p.center), float(p.size)
    radius = np.linalg.norm(pos[:, :2] - c[:2], axis=1)
    np.testing.assert_allclose(radius, r, rtol=1e-4)
    # more than one full lap: the extremes sit at centre ± radius
    assert (pos[:, 0].max() + pos[:, 0].min()) / 2 == pytest.approx(c[0], abs=1e-3)
    assert (pos[:, 1].max() + pos[:, 1].min()) / 2 == pytest.approx(c[1], abs=1e-3)
    assert pos[:, 0].max() - pos[:, 0].min() == pytest.approx(2 * r, rel=1e-4)
    if kind == "circle":
        np.testing.assert_allclose(pos[:, 2], c[2], atol=1e-6)


def test_start_point_and_direction(paths):
    """Phase 0.3 starts at angle 0.3·2π; direction −1 turns clockwise seen from above (z up)."""
    p, pos, vel, _, _ = paths["circle"]
    angle = 2 * math.pi * 0.3
    np.testing.assert_allclose(pos[0, :2] - np.asarray(p.center)[:2], 1.3 * np.array([math.cos(angle), math.sin(angle)]), atol=1e-5)
    rel = pos[:, :2] - np.asarray(p.center)[:2]
    angular_momentum_z = rel[:, 0] * vel[:, 1] - rel[:, 1] * vel[:, 0]
    assert np.all(angular_momentum_z[1:] < 0)


def test_helix_descends_pitch_per_turn_at_constant_3d_speed(paths):
    p, pos, vel, plus, minus = paths["helix"]
    c, pitch, speed = np.asarray(p.center), float(p.pitch), float(p.speed)
    angle = np.unwrap(np.arctan2(pos[:, 1] - c[1], pos[:, 0] - c[0]))
    turns = float(p.direction) * (angle - angle[0]) / (2 * np.pi)
    assert turns[-1] > 1.5  # more than one full turn in the window
    np.testing.assert_allclose(pos[:, 2] - c[2], -pitch * turns, atol=2e-4)
    # one full turn from the start: z down by exactly one pitch
    k = np.argmin(np.abs(turns - 1.0))
    assert (pos[0, 2] - pos[k, 2]) / turns[k] == pytest.approx(pitch, rel=1e-3)
    after = TIMES > RAMP + DT
    np.testing.assert_allclose(np.linalg.norm(vel[after], axis=1), speed, rtol=1e-3)
    fd = (plus[after].astype(np.float64) - minus[after]) / (2 * DT)
    np.testing.assert_allclose(np.linalg.norm(fd, axis=1), speed, rtol=1e-3)
    assert np.all(vel[after, 2] < 0)  # positive pitch: always going down


def test_lemniscate_extent_constant_speed_and_crossing(paths):
    p, pos, vel, _, _ = paths["lemniscate"]
    c, a, h = np.asarray(p.center), float(p.size), float(p.heading)
    rel = pos[:, :2] - c[:2]
    # rotate back by the heading into the figure's own frame
    x = math.cos(h) * rel[:, 0] + math.sin(h) * rel[:, 1]
    y = -math.sin(h) * rel[:, 0] + math.cos(h) * rel[:, 1]
    assert x.max() == pytest.approx(a, rel=1e-4) and x.min() == pytest.approx(-a, rel=1e-4)
    assert y.max() == pytest.approx(a / (2 * math.sqrt(2)), rel=1e-3)
    assert y.min() == pytest.approx(-a / (2 * math.sqrt(2)), rel=1e-3)
    assert 1 / (2 * math.sqrt(2)) == pytest.approx(0.3536, abs=1e-4)
    # the Bernoulli curve itself: (x² + y²)² = a² (x² − y²)
    np.testing.assert_allclose((x**2 + y**2) ** 2, a**2 * (x**2 - y**2), atol=1e-4)
    np.testing.assert_allclose(pos[:, 2], c[2], atol=1e-6)
    speed = np.linalg.norm(vel[TIMES > RAMP], axis=1)
    np.testing.assert_allclose(speed, float(p.speed), rtol=1e-3)  # float32 ripple is ~1e-6
    assert np.linalg.norm(rel, axis=1).min() < 0.45 * 0.005  # passes through its centre
    assert float(path_length("lemniscate", _params("lemniscate", size=1.0))) == pytest.approx(2 * LEMNISCATE_CONSTANT, rel=1e-5)


@pytest.mark.parametrize("kind", KINDS)
def test_ramp_half_speed_continuity_and_exact_velocity(ref, paths, kind):
    p, pos, vel, plus, minus = paths[kind]
    speed = float(p.speed)
    _, v_half = ref(kind, p, jnp.full(TIMES.shape, RAMP / 2))
    assert float(jnp.linalg.norm(v_half[0])) == pytest.approx(speed / 2, rel=1e-3)
    assert np.linalg.norm(vel[0]) == pytest.approx(0.0, abs=1e-7)  # starts from rest
    # continuity: consecutive samples 5 ms apart never jump, in position or velocity
    step = TIMES[1] - TIMES[0]
    assert np.abs(np.diff(pos, axis=0)).max() <= speed * step * 1.02
    assert np.abs(np.diff(vel, axis=0)).max() < 0.01
    # velocity = derivative of the position (central differences, float32 positions)
    fd = (plus.astype(np.float64) - minus) / (2 * DT)
    np.testing.assert_allclose(vel, fd, atol=2e-3)
    away = (np.abs(TIMES - RAMP) > 2 * DT) & (TIMES > 2 * DT)  # the acceleration jumps at 0 and at the ramp end
    np.testing.assert_allclose(vel[away], fd[away], atol=3e-4)


@pytest.mark.parametrize("kind", KINDS)
def test_lap_time_returns_to_the_same_point(ref, kind):
    p = _params(kind)
    lap = float(path_length(kind, p)) / float(p.speed)
    t0 = RAMP + 1.234 + np.zeros_like(TIMES)
    a, va = ref(kind, p, jnp.asarray(t0))
    b, vb = ref(kind, p, jnp.asarray(t0 + lap))
    drop = np.array([0.0, 0.0, float(p.pitch)])
    np.testing.assert_allclose(np.asarray(b[0]) + drop, np.asarray(a[0]), atol=2e-4)
    np.testing.assert_allclose(vb[0], va[0], atol=2e-3)
    half, _ = ref(kind, p, jnp.asarray(t0 + lap / 2))
    assert np.linalg.norm(np.asarray(half[0, :2] - a[0, :2])) > 0.5  # half a lap is elsewhere


def test_shapes_and_zero_ramp():
    p = _params("circle", ramp_time=0.0)
    pos, vel = reference("circle", p, 0.0)
    assert pos.shape == (3,) and vel.shape == (3,)
    assert float(jnp.linalg.norm(vel)) == pytest.approx(0.45, rel=1e-5)  # full speed at once, no NaN
    pos, vel = reference("circle", p, jnp.array([0.0, 1.0, 2.0]))
    assert pos.shape == (3, 3) and np.all(np.isfinite(vel))
    before, _ = reference("circle", _params("circle"), -1.0)  # before the start: hold the start point
    start, _ = reference("circle", _params("circle"), 0.0)
    np.testing.assert_allclose(before, start)


def test_sample_params_deterministic_and_in_range(sample, sample_batch):
    cfg = TrajectoryConfig(center_xy=3.0, center_z=(-8.0, -4.0))
    keys = jax.random.split(jax.random.PRNGKey(2), 64)
    for kind in KINDS:
        batch, (pos, vel) = sample_batch(kind, keys, cfg)
        again, _ = sample_batch(kind, keys, cfg)
        jax.tree.map(np.testing.assert_array_equal, batch, again)  # same rng -> identical
        # different rng -> different draws
        assert len(np.unique(batch.speed)) == 64 and len(np.unique(batch.size)) == 64
        assert len(np.unique(batch.center[:, 0])) == 64
        if kind == "circle":  # one draw on its own equals the same key's row of the vmapped batch
            one = sample(kind, keys[5], cfg)
            jax.tree.map(lambda x, y: np.testing.assert_array_equal(x, y[5]), one, batch)
        assert batch.center.shape == (64, 3) and batch.speed.shape == (64,)
        assert np.all((batch.speed >= 0.2) & (batch.speed <= 0.5))
        assert np.all((batch.size >= 1.0) & (batch.size <= 2.0))
        assert np.all(np.abs(batch.center[:, :2]) <= 3.0)
        assert np.all((batch.center[:, 2] >= -8.0) & (batch.center[:, 2] <= -4.0))
        assert set(np.asarray(batch.direction).tolist()) == {-1.0, 1.0}
        assert np.all((batch.phase >= 0) & (batch.phase < 1)) and np.ptp(batch.phase) > 0.5
        np.testing.assert_array_equal(batch.ramp_time, 2.0)
        if kind == "helix":
            assert np.all((batch.pitch >= 0.3) & (batch.pitch <= 0.6))
        else:
            np.testing.assert_array_equal(batch.pitch, 0.0)
        if kind == "lemniscate":
            assert np.all((batch.heading >= 0) & (batch.heading < 2 * np.pi)) and np.ptp(batch.heading) > 3
        else:
            np.testing.assert_array_equal(batch.heading, 0.0)
        # a batch of paths evaluates under vmap
        assert pos.shape == (64, 3) and np.all(np.isfinite(vel))


def test_sample_params_switches(sample):
    cfg = TrajectoryConfig(random_direction=False, random_phase=False, random_heading=False, speed=(0.3, 0.3))
    p = sample("lemniscate", jax.random.PRNGKey(3), cfg)
    assert float(p.direction) == 1.0 and float(p.phase) == 0.0 and float(p.heading) == 0.0
    assert float(p.speed) == pytest.approx(0.3)
    pos, _ = reference("lemniscate", p, 0.0)  # phase 0, heading 0: starts at (a, 0) from the centre
    np.testing.assert_allclose(pos - p.center, [float(p.size), 0.0, 0.0], atol=1e-5)


@pytest.mark.parametrize(
    "field,value",
    [
        ("speed", (0.5, 0.2)),
        ("speed", (0.0, 0.5)),
        ("size", (-1.0, 2.0)),
        ("size", (1.0, math.inf)),
        ("helix_pitch", (0.6, 0.3)),
        ("center_z", (-4.0, -6.0)),
        ("center_xy", -1.0),
        ("ramp_time", -0.5),
        ("ramp_time", math.nan),
    ],
)
def test_config_rejects_bad_values(field, value):
    with pytest.raises(ValueError, match=field) as err:
        TrajectoryConfig(**{field: value})
    assert str(value) in str(err.value)


def test_config_is_an_immutable_value():
    cfg = TrajectoryConfig()
    assert cfg == TrajectoryConfig() and hash(cfg) == hash(TrajectoryConfig())
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.speed = (0.1, 0.2)


def test_unknown_kind_lists_kinds():
    p = _params("circle")
    for call in (
        lambda: sample_params("square", jax.random.PRNGKey(0), TrajectoryConfig()),
        lambda: reference("square", p, 0.0),
        lambda: path_length("square", p),
    ):
        with pytest.raises(ValueError, match="square") as err:
            call()
        assert all(kind in str(err.value) for kind in KINDS)
