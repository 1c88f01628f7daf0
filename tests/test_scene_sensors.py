"""The sensors that see the scene (altimeter, sonar): ranges against geometry worked out here, what a
beam that meets nothing reads, noise and bins from long samples, update rates, batches and
gradients, and their place in an env's observation."""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import marinejax
from marinejax.errors import UserError
from marinejax.frames import quat_from_euler, quat_to_mat
from marinejax.physics import VehicleState
from marinejax.plant import Plant, PlantConfig
from marinejax.plant.altimeter import Altimeter, AltimeterConfig
from marinejax.plant.rays import fan
from marinejax.plant.scene_sensors import SceneSensors
from marinejax.plant.sensors import SensorConfig, SensorSuite
from marinejax.plant.sonar import Sonar, SonarConfig

SEABED_Z = -5.0  # the seabed scene's plane, m


def _state(plant, position, roll=0.0, pitch=0.0, yaw=0.0):
    vs = VehicleState(position=jnp.asarray(position, jnp.float32), quaternion=quat_from_euler(roll, pitch, yaw),
                      velocity=jnp.zeros(3), angular_velocity=jnp.zeros(3), actuators=jnp.zeros(plant.vehicle.num_actuators))
    return plant.init(jax.random.PRNGKey(0), plant.nominal_params(), vs), vs


def _plant(scene, **sensors):
    """The Heavy in `scene` with both sensors (ideal unless given settings), the sonar at 64 beams of
    4 rays (its vertical aperture resolved)."""
    return Plant("bluerov2_heavy", PlantConfig(scene=scene, sensors=SensorConfig(
        altimeter=AltimeterConfig(enabled=True, **sensors.get("altimeter", {"ideal": True})),
        sonar=SonarConfig(enabled=True, beams=64, rows=4, **sensors.get("sonar", {"ideal": True})))))


def _readings(plant, state, key=jax.random.PRNGKey(1)):
    return jax.jit(lambda s, k: plant.scene_sensors.init(k, plant.cast(plant.nominal_params(), s)))(state, key)


def _plane_ranges(origin, directions, plane_z, max_range):
    """Distance along each world direction from `origin` to the plane z = plane_z (max_range if none)."""
    down = directions[..., 2] < 0
    t = np.where(down, (plane_z - origin[2]) / np.where(down, directions[..., 2], -1.0), np.inf)
    return np.where(t <= max_range, t, max_range)


@pytest.fixture(scope="module")
def seabed():
    return _plant("seabed")


def test_over_a_flat_seabed_every_beam_reads_its_geometric_range(seabed):
    """Rolled 0.2 rad and pitched 0.1 rad, 2 m above the seabed: each altimeter beam, and each
    sonar beam (the nearest of its rays), at the distance along it to the plane z = −5 m."""
    state, vs = _state(seabed, [1.0, -2.0, -3.0], roll=0.2, pitch=0.1, yaw=0.7)
    out = _readings(seabed, state)
    rot = np.asarray(quat_to_mat(vs.quaternion))
    for name, sensor in seabed.scene_sensors.sensors.items():
        origin = np.asarray(vs.position) + rot @ np.asarray(sensor.mount)
        expected = _plane_ranges(origin, np.asarray(sensor.directions) @ rot.T, SEABED_Z, sensor.config.max_range)
        if name == "sonar":
            expected = expected.min(axis=-1)
        np.testing.assert_allclose(out[name].reading.ranges, expected, rtol=1e-5, atol=1e-5, err_msg=name)
    alt = out["altimeter"].reading
    assert bool(alt.lock) and bool(np.all(alt.valid))
    # level, the DVL reports its height: 2 m less its 0.15 m mount below the CG
    level, _ = _state(seabed, [0.0, 0.0, -3.0])
    np.testing.assert_allclose(_readings(seabed, level)["altimeter"].reading.altitude, 1.85, atol=1e-5)


def test_beams_that_meet_nothing_read_the_maximum_range_and_are_flagged():
    """Open water has no seabed to range on (its seabed is drawn only); in the seabed scene, beams
    pointing up or beyond their maximum range see nothing either."""
    open_water = _plant("open_water")
    out = _readings(open_water, _state(open_water, [0.0, 0.0, -3.0])[0])
    assert not np.any(out["sonar"].reading.hit) and np.all(out["sonar"].reading.ranges == 20.0)
    alt = out["altimeter"].reading
    assert not np.any(alt.valid) and not bool(alt.lock) and float(alt.altitude) == 50.0
    # 30 m above the seabed with a 20 m sonar; upside down, the altimeter looks at the surface
    short = _plant("seabed", altimeter={"ideal": True, "max_range": 20.0})
    high = _readings(short, _state(short, [0.0, 0.0, 25.0])[0])
    assert not np.any(high["sonar"].reading.hit) and not np.any(high["altimeter"].reading.valid)
    flipped = _readings(short, _state(short, [0.0, 0.0, -3.0], roll=math.pi)[0])
    assert not np.any(flipped["altimeter"].reading.valid)


def test_a_box_appears_at_its_bearing_and_range(tmp_path):
    """A tall box whose face is 4.8 m from the sonar, square to the bearing 30° left: the beams
    within its width (45, 46, 47 of 64 over ±65°) see it at 4.8 m, and no other beam sees anything."""
    az = math.radians(30.0)
    mount = np.array([0.25, 0.0, 0.0])
    centre = mount + 5.0 * np.array([math.cos(az), math.sin(az), 0.0]) + [0.0, 0.0, -2.0]
    path = tmp_path / "box.xml"
    path.write_text(
        '<mujoco><option><flag contact="disable" constraint="disable"/></option><worldbody>'
        f'<geom name="box" type="box" pos="{centre[0]} {centre[1]} {centre[2]}" euler="0 0 30" size="0.2 0.2 1"/>'
        "</worldbody></mujoco>")
    plant = _plant(str(path))
    sonar = _readings(plant, _state(plant, [0.0, 0.0, -2.0])[0])["sonar"].reading
    beam_az = np.degrees(np.linspace(-65, 65, 64) * math.pi / 180)
    assert np.nonzero(np.asarray(sonar.hit))[0].tolist() == [45, 46, 47], beam_az[[45, 46, 47]]
    expected = 4.8 / np.cos(np.radians(beam_az[[45, 46, 47]] - 30.0))
    np.testing.assert_allclose(np.asarray(sonar.ranges)[[45, 46, 47]], expected, rtol=1e-5)


def test_the_incidence_angle_of_each_geom_kind_is_the_closed_form_one(tmp_path):
    """Rays at known geometry (`Plant.cast(incidence=True)`), against the closed forms: a sphere of
    radius R met at b off its centre line, cos = √(1 − (b/R)²); the side of an upright capsule of
    radius r likewise; a box's face met at 25° from its normal; the seabed plane met 40° from the
    vertical; an ellipsoid on its long axis head on. A missed ray reads 0."""
    r_sphere, r_capsule, b = 0.5, 0.3, 0.2
    path = tmp_path / "shapes.xml"
    path.write_text(
        '<mujoco><option><flag contact="disable" constraint="disable"/></option><worldbody>'
        '<geom name="seabed" type="plane" pos="0 0 -10" size="50 50 0.1"/>'
        f'<geom name="sphere" type="sphere" pos="5 0 0" size="{r_sphere}"/>'
        f'<geom name="capsule" type="capsule" pos="0 5 0" size="{r_capsule} 1"/>'
        '<geom name="box" type="box" pos="-5 0 0" euler="0 0 25" size="0.3 1 1"/>'
        '<geom name="ellipsoid" type="ellipsoid" pos="0 -5 0" euler="0 0 90" size="1 0.3 0.2"/>'
        "</worldbody></mujoco>")
    plant = _plant(str(path))
    state, _ = _state(plant, [0.0, 0.0, 0.0])
    tilt = math.radians(40.0)
    directions = jnp.asarray([
        [5.0, b, 0.0],  # passes b from the sphere's centre
        [b * 5.0 / math.sqrt(25.0 - b**2), 5.0, 0.0],  # b from the capsule's axis
        [-1.0, 0.0, 0.0],  # onto the box's face, whose normal is turned 25° from −x
        [math.sin(tilt), 0.0, -math.cos(tilt)],  # the seabed, 10 m down (the sphere is above the ray)
        [0.0, -1.0, 0.0],  # the ellipsoid's long axis, turned onto y
        [0.0, 0.0, 1.0],  # up: nothing
    ], jnp.float32)
    directions = directions / jnp.linalg.norm(directions, axis=-1, keepdims=True)
    cast = jax.jit(lambda s: plant.cast(plant.nominal_params(), s)(jnp.zeros(3), directions, 50.0, incidence=True))
    dist, hit, cos = (np.asarray(x) for x in cast(state))
    assert hit.tolist() == [True] * 5 + [False]
    expected = [math.sqrt(1 - (b / r_sphere) ** 2), math.sqrt(1 - (b / r_capsule) ** 2), math.cos(math.radians(25.0)),
                math.cos(tilt), 1.0, 0.0]
    np.testing.assert_allclose(cos, expected, atol=2e-4)
    np.testing.assert_allclose(dist[3], 10.0 / math.cos(tilt), rtol=1e-5)


def test_echo_intensity_is_lamberts_law_of_the_nearest_echo_in_each_beam(seabed):
    """With `intensity`, each beam's echo intensity is cos² of the incidence angle of its nearest
    echo (over the flat seabed: the ray whose range is reported), 0 for a beam without an echo, and
    the observation holds the ranges (field `sonar`), then the intensities (`sonar_intensity`)."""
    plant = _plant("seabed", sonar={"ideal": True, "intensity": True})
    state, vs = _state(plant, [1.0, -2.0, -3.0], roll=0.2, pitch=0.1, yaw=0.7)
    sonar = plant.scene_sensors.sensors["sonar"]
    reading = _readings(plant, state)["sonar"].reading
    rot = np.asarray(quat_to_mat(vs.quaternion))
    world = np.asarray(sonar.directions) @ rot.T  # (beams, rows, 3)
    origin = np.asarray(vs.position) + rot @ np.asarray(sonar.mount)
    ranges = _plane_ranges(origin, world, SEABED_Z, sonar.config.max_range)
    nearest = ranges.argmin(axis=-1)
    cos = np.abs(world[np.arange(len(nearest)), nearest, 2])  # the seabed's normal is +z
    expected = np.where(ranges.min(axis=-1) < sonar.config.max_range, cos**2, 0.0)
    assert expected.min() < 0.05 and expected.max() > 0.25  # grazing to steep: a real spread, not a constant
    np.testing.assert_allclose(reading.intensity, expected, atol=1e-4)
    np.testing.assert_allclose(sonar.observe(reading), np.concatenate([reading.ranges, reading.intensity]))
    assert sonar.observation_size == 2 * sonar.config.beams
    env = marinejax.make("BlueROV2Heavy-ObstacleAvoidance", **{"sensors.sonar.intensity": True})
    beams, layout = env.config.sensors.sonar.beams, {f["name"]: f for f in env.observation_layout()}
    ranges, intensity = layout["sonar"], layout["sonar_intensity"]  # two fields: the ranges, then the intensities
    assert (ranges["stop"] - ranges["start"], ranges["unit"]) == (beams, "m")
    assert (intensity["start"], intensity["stop"], intensity["unit"]) == (ranges["stop"], ranges["stop"] + beams, "1")
    assert env.observation_size == intensity["stop"]


def test_echo_intensity_in_a_scene_with_meshes_is_refused(tmp_path):
    path = tmp_path / "mesh.xml"
    path.write_text('<mujoco><asset><mesh name="rock" vertex="0 0 0 1 0 0 0 1 0 0 0 1"/></asset><worldbody>'
                    '<geom name="rock" type="mesh" mesh="rock" pos="3 0 0"/></worldbody></mujoco>')
    _plant(str(path))  # ranges alone: fine
    with pytest.raises(UserError, match="'sensors.sonar.intensity'.*needs primitive geoms"):
        _plant(str(path), sonar={"ideal": True, "intensity": True})


def test_noise_bins_and_dropouts_match_their_settings_over_long_samples():
    """4000 pings at a fixed pose 5.5 m over the seabed, rolled so that the sonar's right half sees
    the seabed and its left half nothing: range noise std, range bins and dropout rates as
    configured (the bins add resolution²/12 to the variance)."""
    plant = _plant("seabed", altimeter={}, sonar={})
    state, vs = _state(plant, [0.0, 0.0, 0.5], roll=0.3)
    sensors = plant.scene_sensors.sensors
    exact = _readings(_plant("seabed"), state)
    keys = jax.random.split(jax.random.PRNGKey(3), 4000)
    cast = jax.jit(jax.vmap(lambda k: {n: s.measure(plant.cast(plant.nominal_params(), state), jax.random.fold_in(k, i))
                                       for i, (n, s) in enumerate(sensors.items())}))(keys)
    c = sensors["sonar"].config
    ranges, hit = np.asarray(cast["sonar"].ranges), np.asarray(cast["sonar"].hit)
    true = np.asarray(exact["sonar"].reading.ranges)
    seen = np.asarray(exact["sonar"].reading.hit)
    assert 0.25 * seen.size < seen.sum() < 0.75 * seen.size
    np.testing.assert_allclose(hit[:, seen].mean(), 1 - c.dropout, atol=4 * math.sqrt(c.dropout / hit[:, seen].size))
    err = (ranges - true)[:, seen][hit[:, seen]]
    np.testing.assert_allclose(err.std(), math.sqrt(c.range_noise**2 + c.range_resolution**2 / 12), rtol=0.03)
    assert abs(err.mean()) < 1e-3
    bins = ranges[hit] / c.range_resolution
    np.testing.assert_allclose(bins, np.round(bins), atol=1e-3)
    assert not np.any(hit[:, ~seen]) and np.all(ranges[:, ~seen] == c.max_range)

    a = sensors["altimeter"].config
    alt = cast["altimeter"]
    lost = ~np.asarray(alt.valid).all(axis=1)
    np.testing.assert_allclose(lost.mean(), a.dropout, atol=4 * math.sqrt(a.dropout / lost.size))
    beam = np.asarray(exact["altimeter"].reading.ranges)
    err = (np.asarray(alt.ranges) - beam)[~lost] / (a.noise_floor + a.noise_fraction * beam)
    np.testing.assert_allclose(err.std(), 1.0, rtol=0.05)


def test_sensors_update_at_their_rate_and_hold_in_between():
    """At 20 Hz control, the 10 Hz sonar takes a new reading every other step (at its phase) and
    the ideal altimeter every step. A stand-in ray cast returns the step's number as the range."""
    cfg = SensorConfig(altimeter=AltimeterConfig(enabled=True, ideal=True),
                       sonar=SonarConfig(enabled=True, range_noise=0.0, range_resolution=0.0, dropout=0.0))
    suite = SceneSensors(cfg, control_dt=0.05)
    assert suite.sensors["sonar"].period == 2 and suite.sensors["altimeter"].period == 1

    def cast_at(k):
        return lambda mount, directions, max_range: (jnp.full(directions.shape[:-1], float(k)), jnp.ones(directions.shape[:-1], bool))

    states = suite.init(jax.random.PRNGKey(0), cast_at(0))
    phase = int(states["sonar"].phase)
    seen = []
    for k in range(1, 7):
        states = suite.step(states, cast_at(k), jax.random.PRNGKey(k))
        seen.append((float(states["sonar"].reading.ranges[0]), float(states["altimeter"].reading.ranges[0])))
    sonar_expected = []
    last = 0.2  # the first reading: range 0 is inside the blind zone and reads min_range
    for k in range(1, 7):
        if (k + phase) % 2 == 0:
            last = float(k)
        sonar_expected.append(last)
    assert [s for s, _ in seen] == sonar_expected
    assert [a for _, a in seen] == [float(k) for k in range(1, 7)]


def test_ray_casts_batch_over_vehicles_and_give_gradients(seabed):
    """vmapped over vehicles, each vehicle's reading is its own; d(altitude)/d(height) = 1 through
    MJX's ray cast (altitude = mean range · cos(beam angle))."""
    heights = jnp.array([-4.0, -3.0, -1.5])

    def altitude(z):
        state, _ = _state(seabed, jnp.array([0.0, 0.0, 0.0]).at[2].set(z))
        return seabed.scene_sensors.sensors["altimeter"].measure(seabed.cast(seabed.nominal_params(), state), jax.random.PRNGKey(0)).altitude

    batch = jax.jit(jax.vmap(altitude))(heights)
    np.testing.assert_allclose(batch, np.asarray(heights) - SEABED_Z - 0.15, atol=1e-5)
    np.testing.assert_allclose(jax.jit(jax.grad(altitude))(-3.0), 1.0, atol=1e-4)


def test_without_bottom_lock_the_dvl_gives_no_velocity():
    suite = SensorSuite(SensorConfig(), control_dt=0.05, gravity=9.81)
    vs = VehicleState(position=jnp.zeros(3), quaternion=quat_from_euler(0.0, 0.0, 0.0), velocity=jnp.array([0.5, 0.0, 0.0]),
                      angular_velocity=jnp.zeros(3), actuators=jnp.zeros(8))
    state, first = suite.init(jax.random.PRNGKey(0), suite.sample_params(jax.random.PRNGKey(1)), vs)
    got = {True: 0, False: 0}
    for k in range(40):
        lock = k < 20
        state, m = suite.step(state, vs, jax.random.PRNGKey(k + 2), bottom_lock=jnp.asarray(lock))
        got[lock] += int(m.dvl_new)
    assert got[False] == 0 and got[True] > 0


def test_bad_settings_are_named():
    with pytest.raises(UserError, match="beams=0"):
        SonarConfig(beams=0)
    with pytest.raises(UserError, match="min_range=60"):
        AltimeterConfig(min_range=60.0)
    with pytest.raises(UserError, match="sensors.sonar.position"):
        SonarConfig(position=(1.0, 0.0))
    with pytest.raises(UserError, match="sensors.sonar.range_noise"):
        marinejax.make("BlueROV2Heavy-StationKeeping", **{"sensors.sonar.range_noise": -1.0})


def test_fan_directions_are_unit_and_span_the_aperture():
    d = fan(64, math.radians(130), 4, math.radians(20), math.radians(10))
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0, atol=1e-6)
    az = np.degrees(np.arctan2(d[..., 1], d[..., 0]))
    el = np.degrees(np.arcsin(d[..., 2]))
    np.testing.assert_allclose(az[[0, -1], 0], [-65, 65], atol=1e-4)
    np.testing.assert_allclose(el[0, [0, -1]], [-20, 0], atol=1e-4)
    assert isinstance(Sonar(SonarConfig(), 0.05).directions, jax.Array) and Altimeter(AltimeterConfig(), 0.05).period == 2


def test_an_env_observes_them_and_a_vehicle_file_places_them():
    """Enabled on any task they join the observation (fields 'altimeter', 'sonar', in the export's
    layout) and the task's info; the REMUS 100's file puts its sonar in the nose."""
    env = marinejax.make("BlueROV2Heavy-StationKeeping", scene="seabed", target_depth=-2.5,
                         **{"sensors.sonar.enabled": True, "sensors.altimeter.enabled": True, "sensors.altimeter.ideal": True,
                            "reset.tilt": 0.0, "reset.angular_velocity": 0.0})
    state = env.reset(jax.random.PRNGKey(0))
    state = env.step(state, jnp.zeros(env.action_size))
    fields = env.observation_fields()
    assert fields["sonar"].stop == env.observation_size and fields["sonar"].stop - fields["sonar"].start == 32
    z = float(state.pipeline_state.physics.data.qpos[2])
    np.testing.assert_allclose(state.obs[fields["altimeter"]], z - SEABED_Z - 0.15, atol=2e-3)  # started level
    assert {f["name"] for f in env.observation_layout()} >= {"altimeter", "sonar"}
    assert state.info["scene_sensors"]["sonar"].reading.ranges.shape == (32,)
    remus = marinejax.make("Remus100-Autopilot").config.sensors
    assert remus.sonar.position == (0.75, 0.0, 0.0) and remus.altimeter.max_range == 30.0


# A new scene sensor, as a user adds one: one module (its config and class) and a field in a
# subclass of SensorConfig; nothing in marinejax edited.
@dataclasses.dataclass(frozen=True)
class EchoSounderConfig:
    enabled: bool = False
    max_range: float = 40.0  # m

    @property
    def sensor(self) -> type:
        return EchoSounder


class EchoSounder:
    """One beam straight down from the vehicle's origin, read every control step."""

    observation_size = 1
    field = ("m", "body", "echo sounder range, straight down")
    period = 1

    def __init__(self, config: EchoSounderConfig, control_dt: float):
        self.config = config
        self.directions = jnp.asarray([[0.0, 0.0, -1.0]])
        self.mount = jnp.zeros(3)

    def measure(self, cast, rng):
        ranges, _hit = cast(self.mount, self.directions, self.config.max_range)
        return ranges

    def observe(self, reading):
        return reading


@dataclasses.dataclass(frozen=True)
class SensorsWithEcho(SensorConfig):
    echo: EchoSounderConfig = EchoSounderConfig()


def test_a_new_scene_sensor_is_one_module_and_a_field():
    """The echo sounder above joins the observation (its field, unit and frame in the layout) and
    the task's info, reads the distance to the seabed, and changes no other sensor's reading."""
    settings = {"scene": "seabed", "target_depth": -2.5, "reset.tilt": 0.0, "reset.angular_velocity": 0.0}
    altimeter = AltimeterConfig(enabled=True)  # noisy, so a changed random stream would show
    env = marinejax.make("BlueROV2Heavy-StationKeeping", sensors=SensorsWithEcho(altimeter=altimeter,
                                                                                 echo=EchoSounderConfig(enabled=True)), **settings)
    plain = marinejax.make("BlueROV2Heavy-StationKeeping", sensors=SensorConfig(altimeter=altimeter), **settings)
    fields = env.observation_fields()
    assert fields["echo"] == slice(plain.observation_size, plain.observation_size + 1)
    assert env.observation_size == plain.observation_size + 1
    assert {"name": "echo", "start": plain.observation_size, "stop": env.observation_size, "unit": "m", "frame": "body",
            "meaning": "echo sounder range, straight down"} in env.observation_layout()
    state, reference = env.reset(jax.random.PRNGKey(3)), plain.reset(jax.random.PRNGKey(3))
    for _ in range(3):
        state, reference = env.step(state, jnp.zeros(env.action_size)), plain.step(reference, jnp.zeros(plain.action_size))
    z = float(state.pipeline_state.physics.data.qpos[2])
    np.testing.assert_allclose(state.info["scene_sensors"]["echo"].reading, [z - SEABED_Z], atol=1e-4)
    np.testing.assert_allclose(state.obs[fields["echo"]], z - SEABED_Z, atol=1e-4)
    np.testing.assert_array_equal(state.info["scene_sensors"]["altimeter"].reading.ranges,
                                  reference.info["scene_sensors"]["altimeter"].reading.ranges)
    np.testing.assert_array_equal(state.obs[: plain.observation_size], reference.obs)
    with pytest.raises(UserError, match="is a section"):
        marinejax.make("BlueROV2Heavy-StationKeeping", sensors=EchoSounderConfig())
