"""The state estimator a vehicle runs on its sensors: a complementary filter, pure JAX.

It turns `sensors.Measurement`s into an estimated `VehicleState`, which the env's observation
reads in sensor mode (the same layout, units and frames as the exact state):
- attitude: the attitude sensor's quaternion; angular velocity: the gyro (bias included);
- body velocity: propagated with the IMU, dv/dt = f + R^T g − ω × v (f the specific force,
  g = (0, 0, −9.81) m/s^2 world), and pulled towards each DVL update by `velocity_gain`;
- position: propagated with R v; z is minus the measured depth; x and y are pulled towards each
  position fix by `position_gain`, comparing the fix with the estimate of the time the fix describes
  (the fix's latency), so a late fix does not drag the estimate backwards.
A sensor marked `ideal` gives the exact value, and the filter passes it through unchanged, so with
every sensor ideal the estimate is the exact state.

Chosen over an EKF because it is what an ArduSub-class vehicle can run with a few lines of code, it
has two gains, and a policy trained on it sees the errors such a filter makes (lag, drift between
fixes). A user with an EKF on the vehicle can replace this module's two functions.
"""

from __future__ import annotations

import jax.numpy as jnp
from flax import struct

from marinejax.frames import quat_to_mat
from marinejax.physics import VehicleState
from marinejax.plant.sensors import Measurement, SensorSuite


@struct.dataclass
class EstimatorState:
    position: jnp.ndarray  # (3,) m, world
    velocity: jnp.ndarray  # (3,) m/s, body
    history: jnp.ndarray  # (max(fix_delay, 1), 3) m, world: the estimates of the last steps, newest first


def estimator_init(suite: SensorSuite, m: Measurement) -> EstimatorState:
    """Start from the first measurement: the fix (x, y), the depth (z) and the DVL velocity."""
    position = jnp.array([m.fix[0], m.fix[1], -m.depth])
    return EstimatorState(position=position, velocity=m.dvl, history=jnp.broadcast_to(position, (max(suite.fix_delay, 1), 3)))


def estimator_update(suite: SensorSuite, est: EstimatorState, m: Measurement) -> EstimatorState:
    """One control step of the filter, after the sensors measured the new state."""
    c, dt = suite.config, suite.control_dt
    rot = quat_to_mat(m.quaternion)
    if c.dvl.ideal:
        velocity = m.dvl
    else:
        accel = m.specific_force + rot.T @ jnp.array([0.0, 0.0, -suite.gravity]) - jnp.cross(m.gyro, est.velocity)
        velocity = est.velocity + dt * accel
        velocity = jnp.where(m.dvl_new, velocity + c.estimator.velocity_gain * (m.dvl - velocity), velocity)
    if c.position_fix.ideal:
        horizontal = m.fix[:2]
    else:
        predicted = est.position + dt * (rot @ velocity)
        # the estimate of the time the fix describes (fix_delay steps ago)
        then = predicted if suite.fix_delay == 0 else est.history[suite.fix_delay - 1]
        horizontal = jnp.where(m.fix_new, predicted[:2] + c.estimator.position_gain * (m.fix[:2] - then[:2]), predicted[:2])
    position = jnp.concatenate([horizontal, -m.depth[None]])
    if c.position_fix.ideal:
        history = est.history
    else:
        # the fix moved the estimate by the same amount at every past step too
        shift = jnp.concatenate([position[:2] - predicted[:2], jnp.zeros(1)])
        history = jnp.concatenate([position[None], est.history[:-1] + shift])
    return EstimatorState(position=position, velocity=velocity, history=history)


def estimated_state(est: EstimatorState, m: Measurement, actuators: jnp.ndarray) -> VehicleState:
    """The estimate as a `VehicleState` (actuators: the actuator states, passed through)."""
    return VehicleState(position=est.position, quaternion=m.quaternion, velocity=est.velocity,
                        angular_velocity=m.gyro, actuators=actuators)
