"""Sensor models of a BlueROV2-class vehicle: what its controller measures instead of the exact state.

Five sensors, sampled once per control step from the exact `VehicleState` (world frame z up, body
frame FLU, SI units):

| sensor | output | model | default values (source) |
|---|---|---|---|
| IMU | gyro (3, rad/s, body), specific force (3, m/s^2, body) | white noise + bias (turn-on draw, random walk) | ICM-20602 (the Navigator's IMU) datasheet: gyro 0.004 °/s/√Hz, accel 100 µg/√Hz, taken over a 10 Hz band; residual biases and walks assumed |
| depth | depth (m, positive down) | offset + white noise, quantised | Blue Robotics Bar30 (MS5837-30BA): 0.2 mbar = 2 mm resolution; noise 2 mm and residual offset ±1 cm after zeroing at the surface assumed |
| attitude | quaternion (w, x, y, z; body → world) | roll/pitch/yaw white noise + yaw drift (random walk) | an AHRS/EKF output (ArduSub); values assumed |
| DVL | velocity over ground (3, m/s, body) | noise ∝ speed + floor, update rate, dropouts | Water Linked DVL A50: ±1.01 % long-term accuracy (standard firmware), ±0.1 cm/s, 10 Hz at 0.3–3 m altitude; dropout rate assumed |
| position fix | position (3, m, world) | white noise, update rate, latency | USBL class (Water Linked Underwater GPS: about 1 % of slant range, i.e. 5 cm at 5 m); rate and latency assumed |

The IMU's specific force is R^T (a − g) with the world acceleration a taken as the change of the world
velocity over the control step: a vehicle at rest measures (0, 0, +g) in the body frame when level.
Sensors slower than the control rate update every `round(1 / (rate_hz · control_dt))` steps, at a
phase drawn per episode, and hold their value in between; sensors faster than it are sampled at
the control rate (one sample per step, the datasheet noise over a 10 Hz band).

These defaults are a BlueROV2's; a vehicle with other sensors overrides any of them in its MJCF file
(`<numeric name="marinejax:sensors:dvl.rate_hz" data="5"/>`, see `vehicle.sensor_settings`).
Every sensor has `ideal`: True gives the exact value at every step (no noise, bias, latency or
dropout), to switch the sensors on one at a time. All parameters can be changed per env
(`--env sensors.dvl.noise_fraction=0.02`); `randomization` scales every noise per episode and draws
the observation and action latencies (control steps) that `envs.base` applies.
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
from flax import struct

from marinejax.config import check_fields, check_range
from marinejax.errors import UserError
from marinejax.frames import quat_from_euler, quat_to_euler, quat_to_mat
from marinejax.physics import VehicleState
from marinejax.plant.altimeter import AltimeterConfig
from marinejax.plant.sonar import SonarConfig

_DEG = math.pi / 180.0


def _check_rate(section: str, rate_hz: float) -> None:
    if not rate_hz > 0:
        raise UserError(f"config 'sensors.{section}.rate_hz' must be > 0, got {rate_hz!r}")


@dataclasses.dataclass(frozen=True)
class ImuConfig:
    """Gyro and accelerometer, body frame, sampled every control step."""

    ideal: bool = False
    gyro_noise: float = 0.004 * _DEG * math.sqrt(10.0)  # rad/s per sample (0.004 °/s/√Hz over 10 Hz)
    gyro_bias: float = 0.1 * _DEG  # rad/s, std of the turn-on bias per axis (after calibration; assumed)
    gyro_bias_walk: float = 1e-4  # rad/s/√s, random walk of the bias (assumed)
    accel_noise: float = 100e-6 * 9.81 * math.sqrt(10.0)  # m/s^2 per sample (100 µg/√Hz over 10 Hz)
    accel_bias: float = 0.02  # m/s^2, std of the turn-on bias per axis (assumed)
    accel_bias_walk: float = 1e-3  # m/s^2/√s (assumed)

    def __post_init__(self):
        check_fields("sensors.imu", self)


@dataclasses.dataclass(frozen=True)
class DepthConfig:
    """Pressure depth sensor: depth = −z (m) + offset + noise, quantised to `resolution`."""

    ideal: bool = False
    noise: float = 0.002  # m, std per sample
    offset: float = 0.01  # m, the offset of an episode is uniform in ± this
    resolution: float = 0.002  # m (0.2 mbar); 0: not quantised
    rate_hz: float = 20.0

    def __post_init__(self):
        check_fields("sensors.depth", self)
        _check_rate("depth", self.rate_hz)


@dataclasses.dataclass(frozen=True)
class AttitudeConfig:
    """Attitude estimate of the autopilot: roll, pitch and yaw with white noise and a yaw drift."""

    ideal: bool = False
    roll_pitch_noise: float = 0.2 * _DEG  # rad, std per sample
    yaw_noise: float = 0.5 * _DEG  # rad, std per sample
    yaw_drift: float = 0.05 * _DEG  # rad/√s, random walk of the heading error

    def __post_init__(self):
        check_fields("sensors.attitude", self)


@dataclasses.dataclass(frozen=True)
class DvlConfig:
    """Doppler velocity log: body-frame velocity over ground, std = noise_fraction · |v| + noise_floor."""

    ideal: bool = False
    noise_fraction: float = 0.0101  # of the speed
    noise_floor: float = 0.001  # m/s
    rate_hz: float = 10.0
    dropout: float = 0.02  # probability that an update is missing (the last value is held)

    def __post_init__(self):
        check_fields("sensors.dvl", self)
        _check_rate("dvl", self.rate_hz)
        if not self.dropout < 1:
            raise UserError(f"config 'sensors.dvl.dropout' must be < 1, got {self.dropout!r}")


@dataclasses.dataclass(frozen=True)
class PositionFixConfig:
    """Acoustic (USBL) position fix: world position with white noise, at `rate_hz`, `latency` late.

    An acoustic fix worsens with the slant range to its beacon (`range_noise`: std per axis grows by
    this fraction of the distance to `beacon`, m, world); a GPS fix exists only at the surface
    (`surface_only`: fixes only while the vehicle is shallower than `surface_depth` m; the
    episode's first fix, the launch position, is always given)."""

    ideal: bool = False
    noise: float = 0.05  # m, std per axis
    rate_hz: float = 2.0
    latency: float = 0.3  # s: a fix describes the position this long before it arrives
    range_noise: float = 0.0  # std per axis per m of slant range to the beacon
    beacon: tuple[float, float, float] = (0.0, 0.0, 0.0)  # m, world
    surface_only: bool = False
    surface_depth: float = 0.5  # m

    def __post_init__(self):
        check_fields("sensors.position_fix", self)
        _check_rate("position_fix", self.rate_hz)
        if len(self.beacon) != 3 or not all(math.isfinite(float(v)) for v in self.beacon):
            raise UserError(f"config 'sensors.position_fix.beacon' must be 3 finite numbers (m, world), got {self.beacon!r}")


@dataclasses.dataclass(frozen=True)
class EstimatorConfig:
    """The complementary filter of `plant.estimator` (gains per update, in [0, 1])."""

    velocity_gain: float = 0.5  # pull of the IMU-propagated velocity towards each DVL update
    position_gain: float = 0.1  # pull of the DVL-propagated horizontal position towards each fix

    def __post_init__(self):
        for name in ("velocity_gain", "position_gain"):
            value = getattr(self, name)
            if not 0 < value <= 1:
                raise UserError(f"config 'sensors.estimator.{name}' must be in (0, 1], got {value!r}")


@dataclasses.dataclass(frozen=True)
class LatencyConfig:
    """Fixed delays, in control steps: the policy sees the observation of `observation` steps ago,
    and the thrusters receive the action of `action` steps ago."""

    observation: int = 0
    action: int = 0

    def __post_init__(self):
        check_fields("sensors.latency", self)


@dataclasses.dataclass(frozen=True)
class SensorRandomizationConfig:
    """Per-episode draws (uniform) when enabled: a factor on every noise std, bias and walk, and the
    latencies in control steps (integers, bounds included)."""

    enabled: bool = False
    noise_scale: tuple[float, float] = (0.5, 2.0)
    observation_latency: tuple[int, int] = (0, 2)
    action_latency: tuple[int, int] = (0, 2)

    def __post_init__(self):
        check_range("sensors.randomization.noise_scale", self.noise_scale, low=0.0)
        check_range("sensors.randomization.observation_latency", self.observation_latency, low=0)
        check_range("sensors.randomization.action_latency", self.action_latency, low=0)


@dataclasses.dataclass(frozen=True)
class SensorConfig:
    """The vehicle's sensors, the estimator its controller runs, and the latencies; `altimeter` and
    `sonar` see the scene (`plant.scene_sensors`, off unless enabled)."""

    imu: ImuConfig = ImuConfig()
    depth: DepthConfig = DepthConfig()
    attitude: AttitudeConfig = AttitudeConfig()
    dvl: DvlConfig = DvlConfig()
    position_fix: PositionFixConfig = PositionFixConfig()
    estimator: EstimatorConfig = EstimatorConfig()
    latency: LatencyConfig = LatencyConfig()
    randomization: SensorRandomizationConfig = SensorRandomizationConfig()
    altimeter: AltimeterConfig = AltimeterConfig()
    sonar: SonarConfig = SonarConfig()


@struct.dataclass
class SensorParams:
    """What is drawn per episode."""

    noise_scale: jnp.ndarray  # () factor on every noise std, bias and walk
    observation_latency: jnp.ndarray  # () int32, control steps
    action_latency: jnp.ndarray  # () int32, control steps
    phase: jnp.ndarray  # (3,) int32: update phase (steps) of depth, DVL and position fix
    depth_offset: jnp.ndarray  # () m


@struct.dataclass
class Measurement:
    """One control step's sensor outputs (held values for sensors that did not update)."""

    gyro: jnp.ndarray  # (3,) rad/s, body
    specific_force: jnp.ndarray  # (3,) m/s^2, body
    quaternion: jnp.ndarray  # (4,) attitude estimate, w x y z, body → world
    depth: jnp.ndarray  # () m, positive down
    dvl: jnp.ndarray  # (3,) m/s, body, over ground
    dvl_new: jnp.ndarray  # () bool: a valid DVL update arrived this step
    fix: jnp.ndarray  # (3,) m, world
    fix_new: jnp.ndarray  # () bool: a position fix arrived this step


@struct.dataclass
class SensorState:
    params: SensorParams
    step: jnp.ndarray  # () int32, control steps since the episode start
    gyro_bias: jnp.ndarray  # (3,) rad/s
    accel_bias: jnp.ndarray  # (3,) m/s^2
    yaw_drift: jnp.ndarray  # () rad
    velocity_world: jnp.ndarray  # (3,) m/s, last step's world velocity (for the specific force)
    positions: jnp.ndarray  # (fix_delay + 1, 3) m, world: exact positions, newest first
    last: Measurement


class SensorSuite:
    """The sensors of one vehicle at one control period; sizes resolved here, methods pure."""

    def __init__(self, config: SensorConfig, control_dt: float, gravity: float):
        self.config = config
        self.control_dt = control_dt
        self.gravity = gravity

        def period(rate_hz: float) -> int:
            return max(1, round(1.0 / (rate_hz * control_dt)))

        c = config
        self.periods = (
            1 if c.depth.ideal else period(c.depth.rate_hz),
            1 if c.dvl.ideal else period(c.dvl.rate_hz),
            1 if c.position_fix.ideal else period(c.position_fix.rate_hz),
        )
        self.fix_delay = 0 if c.position_fix.ideal else round(c.position_fix.latency / control_dt)
        r = c.randomization
        self.max_observation_latency = r.observation_latency[1] if r.enabled else c.latency.observation
        self.max_action_latency = r.action_latency[1] if r.enabled else c.latency.action

    def sample_params(self, rng: jax.Array) -> SensorParams:
        c = self.config
        k = jax.random.split(rng, 5)
        r = c.randomization
        if r.enabled:
            scale = jax.random.uniform(k[0], minval=r.noise_scale[0], maxval=r.noise_scale[1])
            obs_lat = jax.random.randint(k[1], (), r.observation_latency[0], r.observation_latency[1] + 1)
            act_lat = jax.random.randint(k[2], (), r.action_latency[0], r.action_latency[1] + 1)
        else:
            scale = jnp.ones(())
            obs_lat = jnp.asarray(c.latency.observation, jnp.int32)
            act_lat = jnp.asarray(c.latency.action, jnp.int32)
        phase = jax.random.randint(k[3], (3,), 0, jnp.asarray(self.periods))
        offset = 0.0 if c.depth.ideal else c.depth.offset
        depth_offset = jax.random.uniform(k[4], minval=-1.0, maxval=1.0) * offset * scale
        return SensorParams(noise_scale=scale, observation_latency=obs_lat, action_latency=act_lat,
                            phase=phase, depth_offset=depth_offset)

    def init(self, rng: jax.Array, params: SensorParams, vs: VehicleState) -> tuple[SensorState, Measurement]:
        """Sensor state at the episode start (turn-on biases drawn) and the first measurement, in
        which every sensor has updated."""
        c = self.config
        k_g, k_a, k_m = jax.random.split(rng, 3)
        s = params.noise_scale
        gyro_bias = jnp.zeros(3) if c.imu.ideal else jax.random.normal(k_g, (3,)) * c.imu.gyro_bias * s
        accel_bias = jnp.zeros(3) if c.imu.ideal else jax.random.normal(k_a, (3,)) * c.imu.accel_bias * s
        velocity_world = quat_to_mat(vs.quaternion) @ vs.velocity
        zero3, false = jnp.zeros(3), jnp.zeros((), bool)
        state = SensorState(
            params=params, step=jnp.zeros((), jnp.int32), gyro_bias=gyro_bias, accel_bias=accel_bias,
            yaw_drift=jnp.zeros(()), velocity_world=velocity_world,
            positions=jnp.broadcast_to(vs.position, (self.fix_delay + 1, 3)),
            last=Measurement(gyro=zero3, specific_force=zero3, quaternion=vs.quaternion, depth=jnp.zeros(()),
                             dvl=zero3, dvl_new=false, fix=zero3, fix_new=false),
        )
        return self._measure(state, vs, k_m, first=True)

    def step(self, state: SensorState, vs: VehicleState, rng: jax.Array,
             bottom_lock: jnp.ndarray | None = None) -> tuple[SensorState, Measurement]:
        """Advance one control step and measure the new exact state `vs`. `bottom_lock` (bool, from
        the altimeter's beams when it is enabled): without it the DVL gives no velocity."""
        return self._measure(state.replace(step=state.step + 1), vs, rng, first=False, bottom_lock=bottom_lock)

    def _measure(self, state: SensorState, vs: VehicleState, rng: jax.Array, first: bool,
                 bottom_lock: jnp.ndarray | None = None) -> tuple[SensorState, Measurement]:
        c, dt, p = self.config, self.control_dt, state.params
        s = p.noise_scale
        k = jax.random.split(rng, 10)
        rot = quat_to_mat(vs.quaternion)
        velocity_world = rot @ vs.velocity
        positions = jnp.concatenate([vs.position[None], state.positions[:-1]])
        update = (state.step + p.phase) % jnp.asarray(self.periods) == 0
        if first:
            update = jnp.ones(3, bool)
        last = state.last

        # IMU: biases walk, then gyro and specific force with white noise
        gyro_bias, accel_bias = state.gyro_bias, state.accel_bias
        accel_world = (velocity_world - state.velocity_world) / dt
        specific_force = rot.T @ (accel_world + jnp.array([0.0, 0.0, self.gravity]))
        gyro = vs.angular_velocity
        if not c.imu.ideal:
            sqdt = math.sqrt(dt)
            gyro_bias = gyro_bias + jax.random.normal(k[0], (3,)) * c.imu.gyro_bias_walk * sqdt * s
            accel_bias = accel_bias + jax.random.normal(k[1], (3,)) * c.imu.accel_bias_walk * sqdt * s
            gyro = gyro + gyro_bias + jax.random.normal(k[2], (3,)) * c.imu.gyro_noise * s
            specific_force = specific_force + accel_bias + jax.random.normal(k[3], (3,)) * c.imu.accel_noise * s

        # attitude estimate
        yaw_drift, quaternion = state.yaw_drift, vs.quaternion
        if not c.attitude.ideal:
            yaw_drift = yaw_drift + jax.random.normal(k[4]) * c.attitude.yaw_drift * math.sqrt(dt) * s
            noise = jax.random.normal(k[5], (3,)) * jnp.array([c.attitude.roll_pitch_noise] * 2 + [c.attitude.yaw_noise]) * s
            euler = quat_to_euler(vs.quaternion) + noise + jnp.array([0.0, 0.0, 1.0]) * yaw_drift
            quaternion = quat_from_euler(euler[0], euler[1], euler[2])

        # depth
        depth = -vs.position[2]
        if not c.depth.ideal:
            depth = depth + p.depth_offset + jax.random.normal(k[6]) * c.depth.noise * s
            if c.depth.resolution > 0:
                depth = jnp.round(depth / c.depth.resolution) * c.depth.resolution
            depth = jnp.where(update[0], depth, last.depth)

        # DVL
        dvl, dvl_new = vs.velocity, jnp.ones((), bool)
        if not c.dvl.ideal:
            std = (c.dvl.noise_fraction * jnp.linalg.norm(vs.velocity) + c.dvl.noise_floor) * s
            dvl_new = update[1] & (jax.random.uniform(k[7]) >= c.dvl.dropout)
            if first:
                dvl_new = jnp.ones((), bool)
            if bottom_lock is not None:
                dvl_new = dvl_new & bottom_lock
            dvl = jnp.where(dvl_new, vs.velocity + jax.random.normal(k[8], (3,)) * std, last.dvl)

        # position fix, of the position fix_delay steps ago
        fix, fix_new = vs.position, jnp.ones((), bool)
        if not c.position_fix.ideal:
            pf = c.position_fix
            fix_new = update[2]
            if pf.surface_only and not first:
                fix_new = fix_new & (positions[-1][2] > -pf.surface_depth)
            std = pf.noise
            if pf.range_noise:
                std = std + pf.range_noise * jnp.linalg.norm(positions[-1] - jnp.asarray(pf.beacon, jnp.float32))
            fix = jnp.where(fix_new, positions[-1] + jax.random.normal(k[9], (3,)) * std * s, last.fix)

        m = Measurement(gyro=gyro, specific_force=specific_force, quaternion=quaternion, depth=depth, dvl=dvl,
                        dvl_new=dvl_new, fix=fix, fix_new=fix_new)
        new = state.replace(gyro_bias=gyro_bias, accel_bias=accel_bias, yaw_drift=yaw_drift,
                            velocity_world=velocity_world, positions=positions, last=m)
        return new, m
