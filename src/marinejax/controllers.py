"""Classical controllers for every task, behind `control.Controller` (what a trained policy uses).

They read the env's observation through `MarineEnv.observation_fields()`, exactly what a policy
sees (in `observation_mode="sensors"` too), and command the thrusters in [−1, 1].

PID (`pid_controller`): one loop per degree of freedom in the body frame on the position error,
its rate (reference minus measured velocity) and its integral, with the reference velocity fed
forward. A cascade of a P position loop around a PI velocity loop is the same law with its three
gains reparametrised (k_p = K_v K_p + K_i, k_d = K_v, k_i = K_i K_p). Designed on the vehicle's
nominal model linearised around hover, one decoupled axis at a time: M_i ë + D_i ė = τ_i, with M_i the
rigid-body plus added mass (inertia) and D_i the linear damping. A PID on that axis gives the
closed loop M s³ + (D + k_d) s² + k_p s + k_i; placing its three poles at −ω (critically damped):
  k_p = 3 M ω², k_d = 3 M ω − D (≥ 0), k_i = M ω³,
with one bandwidth ω for translation and one for rotation, twice as fast (`PIDConfig`). The
bandwidth is tuned per env by `tune`: the one of a fixed grid with the lowest mean error over
episodes drawn from a seed other than the evaluation's (the thruster lag and the 20 Hz control
rate, which the design model leaves out, are what stops higher bandwidths from paying off).
The integral is the env's leaky integral of the error (in the observation); roll and pitch have
no integral (k_i = 0 leaves
M s² + 3 M ω s + 3 M ω²: poles at √3 ω with damping ratio √3/2): the restoring wrench (weight,
buoyancy, centre of buoyancy) is compensated from the measured attitude instead.
Feedforward: the reference velocity, and the damping it needs (linear and quadratic). The wrench
is allocated to the thrusters with the pseudo-inverse of the allocation matrix (least squares:
the 6-thruster BlueROV2 cannot make a pitch moment) and turned into throttles through the inverse
of the T200 curve at the nominal supply voltage. The thruster lag is not in the design model.

LQR (`lqr_controller`, an LQI: the integral states are the observation's), designed on the coupled
hover model with the thrusts as inputs (`lqr_gain`), so it knows which wrenches the vehicle can make;
weights by Bryson's rule, with the position scale tuned by `tune` like the PID's bandwidth. Same
feedforward as the PID.

Torpedo autopilot (`torpedo_autopilot`, the autopilot task of torpedo AUVs; Fossen 2021 chapter 16,
as the REMUS reference implements it): depth by successive loop closure, an outer PI on the depth
error giving a pitch command (θ_d = K_z (e + ∫e / T_z), limited to ±`max_pitch`; K_z tuned by
`tune`, the reference's 0.1 rad/m in the grid) and an inner PID on pitch with heave-velocity
feedback driving the stern planes (the reference's gains: 5, 2, 0.3 per rad, 5 per m/s); heading by
a PD on the heading error and the yaw rate driving the rudder; speed by propeller feedforward (the shaft speed of the
steady straight run, linear in speed: max_rpm at `top_speed`) plus a PI on the speed error. Angles
as the reference's: a positive rudder turns to starboard, positive stern planes pitch the nose down.
On a path-following task (`los`) the same loops take their pitch and heading commands from integral
line-of-sight guidance (`_line_of_sight`, Fossen 2021 section 12.4) with its distance Δ tuned by `tune`,
the path's curvature as a yaw-rate feedforward and an integral on the heading error (the rudder a
steady turn needs).
On terrain following (`terrain`) the depth loop anticipates the seabed: its error is the measured
altitude error blended with the one over the seabed the sonar sees ahead (`altitude_error_ahead`,
about 4-12 m ahead), (1 − w) e + w e_ahead, with the weight w tuned by `tune` and the depth gain the
autopilot's tuning on that task (0.8 rad per m).

Obstacle avoidance (`avoid_controller`): follow-the-gap on the sonar's range image steering the PID
towards a point ahead on the free beam nearest the goal (`_avoid_law`), its safe range tuned by `tune`.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from marinejax.config import check_fields, check_nonnegative
from marinejax.control import Controller
from marinejax.envs.base import MarineEnv
from marinejax.errors import UserError
from marinejax.plant import Plant
from marinejax.actuators import state_ranges
from marinejax.actuators.fin import steering_mix
from marinejax.actuators.t200 import full_thrust, inverse_t200, only_t200


@dataclasses.dataclass(frozen=True)
class PIDConfig:
    """Closed-loop bandwidths (rad/s): the triple pole of each axis sits at −bandwidth."""

    translation_bandwidth: float = 1.5
    rotation_bandwidth: float = 3.0

    def __post_init__(self):
        check_fields("PIDConfig", self, strict=True)


@dataclasses.dataclass(frozen=True)
class PIDGains:
    kp: np.ndarray  # (6,) N/m, N m/rad
    kd: np.ndarray  # (6,) N s/m, N m s/rad
    ki: np.ndarray  # (6,) N/(m s), N m/(rad s); zero for roll and pitch


def pid_gains(env: MarineEnv, config: PIDConfig = PIDConfig()) -> PIDGains:
    """Gains by pole placement on the nominal hover model of `env`'s vehicle (module docstring)."""
    p = env.plant.nominal_params()
    mass = np.concatenate([np.full(3, float(p.mass)), np.asarray(p.inertia, float)]) + np.asarray(p.hydro.added_mass, float)
    damping = np.asarray(p.hydro.linear_damping, float)
    w = np.array([config.translation_bandwidth] * 3 + [config.rotation_bandwidth] * 3)
    kp = 3 * mass * w**2
    kd = np.maximum(3 * mass * w - damping, 0.0)
    ki = mass * w**3 * np.array([1, 1, 1, 0, 0, 1.0])
    return PIDGains(kp=kp, kd=kd, ki=ki)


def inverse_thrust(plant: Plant):
    """throttle(thrust): the inverse of each thruster's steady T200 curve at the plant's nominal voltage
    and gains (thrust in N along the thruster axis → throttle in [−1, 1]; beyond the curve: ±1)."""
    group = only_t200(plant.sys.actuators, "the classical controllers")
    p = group.params
    inverse = inverse_t200(group.design.curve, float(p.voltage))
    gain = jnp.asarray(p.gain)
    return lambda thrust: inverse(thrust / gain)


@dataclasses.dataclass(frozen=True)
class _Hover:
    """What both controllers know of the vehicle: its nominal model around hover, and how to read the
    observation and command the thrusters."""

    fields: dict
    mass: np.ndarray  # (6,) rigid + added, kg and kg m^2
    damping: np.ndarray  # (6,) linear, N s/m and N m s/rad
    quadratic: np.ndarray  # (6,)
    net_up: float  # N, buoyancy minus weight along world up
    buoyancy: float  # N
    cob: np.ndarray  # (3,) m, body, from the centre of gravity
    allocation: np.ndarray  # (6, N)
    throttle: object  # thrust (N) → throttle
    max_thrust: float  # N, the smaller of the forward and reverse steady thrust at the nominal voltage


def _hover(env: MarineEnv) -> _Hover:
    if env.config.action_mode != "thrusters":
        raise UserError(f"the classical controllers command thrusters; the env has action_mode={env.config.action_mode!r}")
    group = only_t200(env.plant.sys.actuators, "the classical controllers")
    p = env.plant.nominal_params()
    t200 = p.actuators[0]
    g = env.plant.gravity
    return _Hover(
        fields=env.observation_fields(),
        mass=np.concatenate([np.full(3, float(p.mass)), np.asarray(p.inertia, float)]) + np.asarray(p.hydro.added_mass, float),
        damping=np.asarray(p.hydro.linear_damping, float), quadratic=np.asarray(p.hydro.quadratic_damping, float),
        net_up=float(p.net_buoyancy(g)), buoyancy=float(p.hydro.fluid_density * p.hydro.volume * g),
        cob=np.asarray(p.hydro.center_of_buoyancy, float), allocation=np.asarray(group.design.allocation, float),
        throttle=inverse_thrust(env.plant), max_thrust=full_thrust(group.design.curve, t200.voltage) * float(np.min(np.asarray(t200.gain))),
    )


def _read(h: _Hover, obs: jax.Array):
    """From the observation: the error [position (body, m), roll, pitch, heading (rad)] to drive to
    zero, the rate error [reference − body velocity, −angular velocity], the integral [position, heading]
    (zeros without one), the world up in the body frame and the reference velocity (body, m/s)."""
    f = h.fields
    up = obs[f["up"]]
    s, c = obs[f["heading"]]
    v_ref = obs[f["reference_velocity"]] if "reference_velocity" in f else jnp.zeros(3)
    roll, pitch = jnp.arctan2(up[1], up[2]), -jnp.arcsin(jnp.clip(up[0], -1.0, 1.0))
    error = jnp.concatenate([obs[f["position_error"]], jnp.stack([-roll, -pitch, jnp.arctan2(s, c)])])
    rate_error = jnp.concatenate([v_ref - obs[f["velocity"]], -obs[f["angular_velocity"]]])
    if "integral_position" in f:
        integral = jnp.concatenate([obs[f["integral_position"]], obs[f["integral_heading"]]])
    else:
        integral = jnp.zeros(4)
    return error, rate_error, integral, up, v_ref


def _feedforward(h: _Hover, up: jax.Array, v_ref: jax.Array) -> jax.Array:
    """Body wrench (6,) that cancels weight and buoyancy (from the measured attitude) and the damping at the reference velocity."""
    restoring = jnp.concatenate([h.net_up * up, jnp.cross(jnp.asarray(h.cob), h.buoyancy * up)])
    drag = jnp.asarray(h.damping[:3]) * v_ref + jnp.asarray(h.quadratic[:3]) * jnp.abs(v_ref) * v_ref
    return jnp.concatenate([drag, jnp.zeros(3)]) - restoring


def _pid_design(env: MarineEnv, config: PIDConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    g = pid_gains(env, config)
    return g.kp, g.kd, g.ki[[0, 1, 2, 5]]


def _pid_law(h: _Hover, gains) -> Controller:
    """The PID control law with gains (kp (6,), kd (6,), ki (4,)): NumPy or traced JAX arrays."""
    kp, kd, ki = (jnp.asarray(g, jnp.float32) for g in gains)
    alloc_pinv = jnp.asarray(np.linalg.pinv(h.allocation), jnp.float32)

    def act(carry, obs, info):
        error, rate_error, integral, up, v_ref = _read(h, obs)
        # the observation's integral is leaky (∫ e exp(−(t−s)/T) ds): close to ∫ e over times below T
        i_term = ki * integral
        tau = kp * error + kd * rate_error + jnp.concatenate([i_term[:3], jnp.zeros(2), i_term[3:]])
        wrench = tau + _feedforward(h, up, v_ref)
        return jnp.clip(h.throttle(alloc_pinv @ wrench), -1.0, 1.0), carry

    return Controller(init=lambda key: (), act=act)


def pid_controller(env: MarineEnv, config: PIDConfig = PIDConfig()) -> Controller:
    """The PID of the module docstring on `env` (thruster action mode), reading its observation."""
    return _pid_law(_hover(env), _pid_design(env, config))


@dataclasses.dataclass(frozen=True)
class LQRConfig:
    """Bryson's rule: each state and input costs (value / its scale)^2. Only `position_scale` is tuned."""

    position_scale: float = 0.05  # m (and m s for the position integral)
    attitude_scale: float = 0.1  # rad (roll, pitch, heading; rad s for its integral)
    velocity_scale: float = 0.5  # m/s
    angular_velocity_scale: float = 1.0  # rad/s

    def __post_init__(self):
        check_fields("LQRConfig", self, strict=True)


def hover_model(env: MarineEnv) -> tuple[np.ndarray, np.ndarray]:
    """(A_d (16, 16), B_d (16, N)): the hover model of `lqr_gain` discretised over control_dt, state
    x = [pose deviation (position m, roll, pitch, yaw rad), velocity deviation (body, 6), integral (4)],
    input the thrusts (N)."""
    import scipy.linalg

    h = _hover(env)
    n_u = h.allocation.shape[1]
    a = np.zeros((16, 16))
    a[0:6, 6:12] = np.eye(6)  # pose rates = velocities
    stiffness = np.zeros((6, 3))  # d(restoring wrench)/d(roll, pitch, yaw) at level
    stiffness[0, 1], stiffness[1, 0] = -h.net_up, h.net_up  # up ≈ (−θ, φ, 1)
    bx, by, bz = h.cob
    stiffness[3, 0], stiffness[4, 1] = -h.buoyancy * bz, -h.buoyancy * bz
    stiffness[5, 0], stiffness[5, 1] = h.buoyancy * bx, h.buoyancy * by
    a[6:12, 3:6] = stiffness / h.mass[:, None]
    a[6:12, 6:12] = -np.diag(h.damping / h.mass)
    leak = 1.0 / env.config.integral_time_constant if env.config.integral_time_constant > 0 else 0.0
    a[12:15, 0:3] = np.eye(3)
    a[15, 5] = 1.0
    a[12:16, 12:16] = -leak * np.eye(4)
    b = np.zeros((16, n_u))
    b[6:12] = h.allocation / h.mass[:, None]
    block = scipy.linalg.expm(np.block([[a, b], [np.zeros((n_u, 16 + n_u))]]) * env.config.control_dt)
    return block[:16, :16], block[:16, 16:]


def lqr_gain(env: MarineEnv, config: LQRConfig = LQRConfig()) -> np.ndarray:
    """K (N, 16): thrusts f = f_ff − K x for x = [−error (6), −rate error (6), −integral (4)] (see
    `_read`), from the discrete Riccati equation of the hover model (`hover_model`).

    Model (body frame, small angles, level hover): position and attitude rates are the body
    velocities; M ν̇ = −D ν + S [φ, θ] + B f, with S the restoring stiffness of weight and buoyancy and
    B the allocation matrix (thrusts as inputs, so the 6-thruster BlueROV2's missing pitch authority
    is in the model); the integral states follow the observation's leaky integral, İ = e − I/T.
    Discretised with a zero-order hold over control_dt; the thruster lag is left out.
    """
    import scipy.linalg

    h = _hover(env)
    ad, bd = hover_model(env)
    c = config
    scales = np.array([c.position_scale] * 3 + [c.attitude_scale] * 3 + [c.velocity_scale] * 3
                      + [c.angular_velocity_scale] * 3 + [c.position_scale] * 3 + [c.attitude_scale])
    if env.config.integral_time_constant == 0:
        scales[12:] = np.inf  # no integral in the observation: do not weigh (nor use) it
    q = np.diag(1.0 / scales**2)
    r = np.eye(bd.shape[1]) / h.max_thrust**2
    p = scipy.linalg.solve_discrete_are(ad, bd, q, r)
    return np.linalg.solve(r + bd.T @ p @ bd, bd.T @ p @ ad)


def _lqr_law(h: _Hover, k) -> Controller:
    """The LQI control law with gain k (N, 16): NumPy or a traced JAX array."""
    k = jnp.asarray(k, jnp.float32)
    alloc_pinv = jnp.asarray(np.linalg.pinv(h.allocation), jnp.float32)

    def act(carry, obs, info):
        error, rate_error, integral, up, v_ref = _read(h, obs)
        x = -jnp.concatenate([error, rate_error, integral])
        thrust = alloc_pinv @ _feedforward(h, up, v_ref) - k @ x
        return jnp.clip(h.throttle(thrust), -1.0, 1.0), carry

    return Controller(init=lambda key: (), act=act)


def lqr_controller(env: MarineEnv, config: LQRConfig = LQRConfig()) -> Controller:
    """LQI on the hover model (`lqr_gain`) with the feedforward of the PID, reading the observation."""
    return _lqr_law(_hover(env), lqr_gain(env, config))


@dataclasses.dataclass(frozen=True)
class TorpedoAutopilotConfig:
    """Gains of the torpedo autopilot (module docstring); angles in rad, depths in m, speeds in m/s."""

    depth_gain: float = 0.1  # K_z, rad of pitch command per m of depth error (tuned)
    depth_integral_time: float = 100.0  # T_z, s
    max_pitch: float = 0.5  # rad, pitch command limit
    pitch_gains: tuple[float, float, float] = (5.0, 2.0, 0.3)  # stern planes per rad, per rad/s, per rad s
    heave_gain: float = 5.0  # stern planes per m/s of heave velocity
    heading_gain: float = 1.0  # rudder per rad of heading error
    heading_derivative_time: float = 2.0  # s: rudder per rad/s of yaw rate = heading_gain × this
    top_speed: float = 2.554  # m/s at the propeller's max_rpm (the REMUS 100's)
    speed_gains: tuple[float, float] = (0.5, 0.1)  # propeller command per m/s, per m
    lookahead: float = 10.0  # m, line-of-sight distance Δ (path following; tuned)
    heading_integral_time: float = 10.0  # s (path following: the steady rudder of a turn)
    # weight of the altitude error over the seabed the sonar sees ahead in the depth error (terrain
    # following's `altitude_error_ahead`; 0: the measured altitude error alone; tuned)
    seabed_ahead: float = 0.0

    def __post_init__(self):
        check_fields("TorpedoAutopilotConfig", self, strict=True, zero_allowed=("seabed_ahead",))
        if not self.seabed_ahead <= 1.0:
            raise UserError(f"TorpedoAutopilotConfig 'seabed_ahead' must be within [0, 1], got {self.seabed_ahead}")
        check_nonnegative(self, ("pitch_gains", "speed_gains"), "TorpedoAutopilotConfig")


@dataclasses.dataclass(frozen=True)
class _Torpedo:
    """What the torpedo autopilot knows of the vehicle and env: the observation layout, the control
    period and the actuators' order (rudder, stern planes, propeller) and ranges."""

    fields: dict
    dt: float
    rudder_max: float  # rad
    stern_max: float  # rad
    rpm_range: tuple[float, float]
    mix: np.ndarray  # (actions, 3): the action of unit [rudder, stern planes, propeller] commands (`steering_mix`)


def _torpedo(env: MarineEnv) -> _Torpedo:
    groups = env.plant.sys.actuators
    kinds = [g.kind.name for g in groups]
    if set(kinds) != {"fin", "propeller"} or not {"depth_error", "tangent"} & set(env.observation_fields()):
        raise UserError(f"the torpedo autopilot needs the autopilot or a path-following task of a vehicle with fins and a "
                        f"propeller; {env.vehicle.name!r} has {kinds} on {type(env).__name__}")
    mix = steering_mix(groups)
    lo, hi = state_ranges(groups)
    first = [int(np.argmax(mix[:, k] != 0)) for k in range(3)]  # the first fin of each command, and the propeller
    return _Torpedo(fields=env.observation_fields(), dt=env.config.control_dt, rudder_max=float(hi[first[0]]),
                    stern_max=float(hi[first[1]]), rpm_range=(float(lo[first[2]]), float(hi[first[2]])), mix=mix)


def _torpedo_design(env: MarineEnv, config: TorpedoAutopilotConfig) -> np.ndarray:
    c = config
    if c.seabed_ahead and "altitude_error_ahead" not in env.observation_fields():
        raise UserError(f"TorpedoAutopilotConfig 'seabed_ahead' ({c.seabed_ahead}) needs the sonar's altitude error ahead: "
                        f"terrain following with 'lookahead' true; {env.vehicle.name!r} on {type(env).__name__} has none")
    return np.array([c.depth_gain, 1.0 / c.depth_integral_time, c.max_pitch, *c.pitch_gains, c.heave_gain, c.heading_gain,
                     c.heading_gain * c.heading_derivative_time, c.top_speed, *c.speed_gains, c.lookahead,
                     c.heading_gain / c.heading_integral_time, c.seabed_ahead])



def _torpedo_law(t: _Torpedo, gains) -> Controller:
    """The controller with gains `_torpedo_design` (NumPy or traced JAX) on the task `t` reads: the
    autopilot's set-points, or line-of-sight guidance on a path-following task (`_line_of_sight`).
    Carry: the integrals of the depth error (m s), of the pitch error (rad s), of the speed error (m)
    and, in path following, of the heading error (rad s)."""
    g = jnp.asarray(gains, jnp.float32)
    kz, kiz, max_pitch, kp, kd, ki, kw, kpsi, kr, top, ks, kis = (g[i] for i in range(12))
    f = t.fields

    def act(carry, obs, info):
        up, omega, v = obs[f["up"]], obs[f["angular_velocity"]], obs[f["velocity"]]
        nose_up = jnp.arcsin(jnp.clip(up[0], -1.0, 1.0))
        i_depth, i_pitch, i_speed, i_heading = carry
        speed_sp = obs[f["set_point_speed"]][0]
        if "tangent" in f:  # path following: the guidance gives the pitch, heading and yaw-rate commands
            pitch_cmd, heading_error, rate_cmd = _line_of_sight(obs, f, g[12], speed_sp)
            pitch_cmd, depth_error = jnp.clip(pitch_cmd, -max_pitch, max_pitch), jnp.zeros(())
            rudder = -kpsi * heading_error + kr * (omega[2] - rate_cmd) - g[13] * i_heading  # positive: to starboard
        else:
            depth_error = obs[f["depth_error"]][0]  # set-point − depth (m, world z up): positive = rise
            if "altitude_error_ahead" in f:  # terrain following: blended with the seabed ahead (weight 0 by default)
                depth_error = (1.0 - g[14]) * depth_error + g[14] * obs[f["altitude_error_ahead"]][0]
            s, c = obs[f["heading"]]
            heading_error = jnp.arctan2(s, c)
            pitch_cmd = jnp.clip(kz * (depth_error + kiz * i_depth), -max_pitch, max_pitch)
            rudder = -kpsi * heading_error + kr * omega[2]  # positive: to starboard
        # stern planes (positive: nose down), the reference's law in FLU: nose-up rate −ω_y, heave −w
        stern = kp * (nose_up - pitch_cmd) - kd * omega[1] + ki * i_pitch - kw * v[2]
        speed_error = obs[f["speed_error"]][0]
        lo, hi = t.rpm_range
        rpm = hi * speed_sp / top + (hi - lo) * (ks * speed_error + kis * i_speed)
        command = jnp.stack([rudder / t.rudder_max, stern / t.stern_max, 2 * (rpm - lo) / (hi - lo) - 1])
        action = command if np.array_equal(t.mix, np.eye(3)) else jnp.asarray(t.mix) @ command  # the fins' share
        # integrate only while unsaturated (anti-windup)
        carry = (i_depth + t.dt * depth_error * (jnp.abs(pitch_cmd) < max_pitch),
                 i_pitch + t.dt * (nose_up - pitch_cmd) * (jnp.abs(stern) < t.stern_max),
                 i_speed + t.dt * speed_error * (jnp.abs(command[2]) < 1.0),
                 i_heading + t.dt * heading_error * (jnp.abs(rudder) < t.rudder_max))
        return jnp.clip(action, -1.0, 1.0), carry

    return Controller(init=lambda key: (jnp.zeros(()),) * 4, act=act)


def _line_of_sight(obs, f, lookahead, speed):
    """Line-of-sight guidance (Fossen 2021, section 12.4) in the horizontal and the vertical plane,
    from the path-following observation (body frame): the course to steer is the path's course plus
    atan(e_y/Δ), the climb angle the path's plus atan(e_z/Δ), e_y and e_z the path's offset to the
    left of and above the vehicle (m); the vehicle's course and climb are its heading and pitch plus
    the angles of its velocity in the body frame (sideslip, angle of attack), so a turn's sideslip
    leaves no offset. The yaw rate to turn at is the path's curvature (from the chord to the first
    previewed point: exact on a circle) times `speed`. Returns the pitch command (rad, nose up), the
    heading error (rad, positive: turn left) and the yaw rate (rad/s, left)."""
    up, closest, tangent, v = obs[f["up"]], obs[f["position_error"]], obs[f["tangent"]], obs[f["velocity"]]
    level = lambda a: a - jnp.dot(a, up) * up  # noqa: E731  (the horizontal part of a body-frame vector)
    left_of = lambda a, b: jnp.arctan2(jnp.dot(up, jnp.cross(a, b)), jnp.dot(a, b))  # noqa: E731  (angle from a to b about up)
    x_h, t_h = level(jnp.array([1.0, 0.0, 0.0])), level(tangent)
    chord = level(obs[f["path_ahead"]][:3] - closest)
    curvature = 2 * jnp.sin(left_of(t_h, chord)) / jnp.maximum(jnp.linalg.norm(chord), 1e-6)
    left = jnp.cross(up, t_h / jnp.maximum(jnp.linalg.norm(t_h), 1e-6))
    e_y, e_z = jnp.dot(closest, left), jnp.dot(closest, up)
    climb = jnp.arcsin(jnp.clip(jnp.dot(tangent, up), -1.0, 1.0))
    sideslip, attack = jnp.arctan2(v[1], v[0]), jnp.arctan2(v[2], v[0])  # velocity's angles left of and above body x
    return (climb + jnp.arctan(e_z / lookahead) - attack, left_of(x_h, t_h) + jnp.arctan(e_y / lookahead) - sideslip,
            speed * curvature)


def torpedo_autopilot(env: MarineEnv, config: TorpedoAutopilotConfig = TorpedoAutopilotConfig()) -> Controller:
    """The torpedo autopilot of the module docstring on `env` (the autopilot task), reading its observation."""
    return _torpedo_law(_torpedo(env), _torpedo_design(env, config))


@dataclasses.dataclass(frozen=True)
class AvoidConfig:
    """Reactive obstacle avoidance on the sonar (`avoid_controller`): the free beam nearest the goal
    steers the PID."""

    safe_range: float = 4.0  # m: a beam is free if its echo is farther than this (or than the goal)
    margin: float = 0.8  # m: half the width a free direction needs (vehicle half-width plus a margin)
    lookahead: float = 2.0  # m: how far ahead of the vehicle the steering point is

    def __post_init__(self):
        check_fields("AvoidConfig", self, strict=True)


def _avoid_model(env: MarineEnv):
    if "sonar" not in env.observation_fields():
        raise UserError("the avoid controller steers on the sonar; enable it (--env sensors.sonar.enabled=true)")
    return _hover(env), env.plant.scene_sensors.sensors["sonar"].azimuth.astype(np.float32)


def _avoid_design(env: MarineEnv, config: AvoidConfig):
    return (*_pid_design(env, PIDConfig()), *(np.float32(v) for v in (config.safe_range, config.margin, config.lookahead)))


def _avoid_law(model, gains) -> Controller:
    """Follow the gap on the sonar's range image (body frame, horizontal): a beam is blocked if some
    echo closer than `safe_range` (or than the goal) lies within `margin` m of its line; the vehicle
    heads for the free beam nearest the goal's bearing and the PID drives it towards a point on it
    `lookahead` m ahead, scaled by cos⁴ of the heading error (it turns on the spot first: the sonar
    sees ahead only), at the goal's depth. With the goal outside the fan, or no free beam, it turns on
    the spot (towards the goal, or to the left); within 1 m of the goal it goes straight to it."""
    h, azimuth = model
    kp, kd, ki, safe_range, margin, lookahead = gains
    pid = _pid_law(h, (kp, kd, ki))
    f = h.fields
    azimuth = jnp.asarray(azimuth)
    half_fov = float(np.max(np.abs(np.asarray(model[1]))))

    def act(carry, obs, info):
        goal = obs[f["position_error"]]
        distance = jnp.linalg.norm(goal[:2])
        goal_bearing = jnp.arctan2(goal[1], goal[0])
        ranges = obs[f["sonar"]]
        close = ranges < jnp.minimum(safe_range, distance + margin)
        # echo j is within `margin` of beam i's line if r_j |sin(a_i − a_j)| < margin in front of the vehicle
        dangle = azimuth[:, None] - azimuth[None, :]
        blocks = close[None, :] & (ranges[None, :] * jnp.abs(jnp.sin(dangle)) < margin) & (jnp.cos(dangle) > 0)
        free = ~jnp.any(blocks, axis=1)
        cost = jnp.where(free, jnp.abs(azimuth - goal_bearing), jnp.inf)
        best = jnp.argmin(cost)
        visible = jnp.abs(goal_bearing) < half_fov
        bearing = jnp.where(visible & jnp.isfinite(cost[best]), azimuth[best], jnp.where(visible, half_fov, goal_bearing))
        advance = jnp.where(visible & jnp.isfinite(cost[best]), 1.0, 0.0) * jnp.maximum(jnp.cos(bearing), 0.0) ** 4
        point = jnp.stack([jnp.cos(bearing), jnp.sin(bearing)]) * advance * jnp.minimum(lookahead, distance)
        far = distance > 1.0
        point = jnp.where(far, point, goal[:2])
        bearing = jnp.where(far, bearing, jnp.arctan2(*obs[f["heading"]]))
        # the body-frame offset whose world vertical is the goal's (up: world up in the body frame), so
        # that a tilted vehicle steering at a point 2 m ahead does not read the goal's distance as height
        up = obs[f["up"]]
        vertical = (up @ goal - up[0] * point[0] - up[1] * point[1]) / jnp.maximum(up[2], 0.5)
        steered = obs.at[f["position_error"]].set(jnp.concatenate([point, vertical[None]]))
        steered = steered.at[f["heading"]].set(jnp.stack([jnp.sin(bearing), jnp.cos(bearing)]))
        return pid.act(carry, steered, info)

    return Controller(init=pid.init, act=act)


def avoid_controller(env: MarineEnv, config: AvoidConfig = AvoidConfig()) -> Controller:
    """Reactive obstacle avoidance (`_avoid_law`) on `env`'s sonar and goal, through the PID."""
    return _avoid_law(_avoid_model(env), _avoid_design(env, config))


# Tuning grids: one scalar per controller, the rest follows from the model (module docstring).
# name: (what the scalar is, grid, config of a value, design: (env, config) -> gains,
#        law: (model, gains) -> Controller, model: env -> what the law knows of the vehicle)
TUNING_GRIDS = {
    "pid": ("translation bandwidth (rad/s; rotation twice)", (1.0, 2.0, 3.0, 4.0, 6.0),
            lambda w: PIDConfig(translation_bandwidth=w, rotation_bandwidth=2 * w), _pid_design, _pid_law, _hover),
    "lqr": ("position scale (m)", (0.2, 0.1, 0.05, 0.02, 0.01), lambda s: LQRConfig(position_scale=s), lqr_gain, _lqr_law, _hover),
    "autopilot": ("depth gain (pitch rad per m)", (0.05, 0.1, 0.2, 0.4, 0.8),
                  lambda k: TorpedoAutopilotConfig(depth_gain=k), _torpedo_design, _torpedo_law, _torpedo),
    # path following turns all the time: a tighter heading loop than the reference's (5 per rad, 1 s)
    "los": ("line-of-sight distance (m)", (2.5, 5.0, 10.0, 20.0),
            lambda d: TorpedoAutopilotConfig(heading_gain=5.0, heading_derivative_time=1.0, lookahead=d),
            _torpedo_design, _torpedo_law, _torpedo),
    # the autopilot anticipating the seabed (terrain following), at the depth gain the autopilot's tuning picks there
    "terrain": ("weight of the seabed ahead", (0.0, 0.15, 0.3, 0.45),
                lambda w: TorpedoAutopilotConfig(depth_gain=0.8, seabed_ahead=w), _torpedo_design, _torpedo_law, _torpedo),
    "avoid": ("safe sonar range (m)", (2.0, 3.0, 4.0, 6.0), lambda d: AvoidConfig(safe_range=d), _avoid_design,
              _avoid_law, _avoid_model),
}
TUNING_SEED = 1  # episodes for tuning; `marinejax eval` evaluates on another seed (12345)
CONTROLLERS = tuple(TUNING_GRIDS)


def tune(name: str, env: MarineEnv, episodes: int = 16, seed: int = TUNING_SEED, progress=None):
    """The config of controller `name` whose grid value gives the lowest mean window error (the task's
    evaluation statistic; `max_distance` for an episode that ended early) over `episodes` episodes of
    `env` from `seed`; returns (config, {value: error (m)}).
    Every grid value runs in one jitted call (the gains are traced), so tuning compiles once."""
    from marinejax.control import run_steps

    if name not in TUNING_GRIDS:
        raise UserError(f"unknown controller {name!r}; valid: {list(CONTROLLERS)}")
    label, grid, make_config, design, law, model = TUNING_GRIDS[name]
    h = model(env)
    stacked = jax.tree.map(lambda *g: jnp.stack([jnp.asarray(x, jnp.float32) for x in g]),
                           *[design(env, make_config(v)) for v in grid])
    steps = env.config.episode_length

    def episode(key, gains):
        controller = law(h, gains)
        state = env.reset(key)
        _, _, recorded = run_steps(env, controller, state, controller.init(key), steps, lambda s: (s.metrics["position_error"], s.done))
        return recorded

    keys = jax.random.split(jax.random.PRNGKey(seed), episodes)
    err, done = jax.jit(jax.vmap(jax.vmap(episode, (0, None)), (None, 0)))(keys, stacked)
    time = env.config.control_dt * np.arange(1, steps + 1)
    errors = {}
    window = np.asarray(env.error_window(time))
    for i, value in enumerate(grid):
        # an episode that ended early (a collision, out of bounds) counts max_distance, as in training
        per_episode = np.asarray(err[i], float)[:, window].mean(axis=1)
        errors[value] = float(np.where(np.asarray(done[i]).max(axis=1) > 0, env.config.max_distance, per_episode).mean())
        if progress is not None:
            progress(f"{name.upper()} tuning: {label} {value:g}: mean error {errors[value]:.4f} m")
    return make_config(min(errors, key=errors.get)), errors


def make_controller(name: str, env: MarineEnv, progress=None) -> tuple[Controller, dict]:
    """A classical controller by name (`CONTROLLERS`), tuned for `env`; returns it and a description
    (settings, gains and tuning results) for reports."""
    config, errors = tune(name, env, progress=progress)
    info = {"controller": name, "config": dataclasses.asdict(config),
            "tuning": {"seed": TUNING_SEED, "parameter": TUNING_GRIDS[name][0],
                       "mean_error_m": {str(k): v for k, v in errors.items()}}}
    if name == "pid":
        gains = pid_gains(env, config)
        info["gains"] = {k: np.round(getattr(gains, k), 3).tolist() for k in ("kp", "kd", "ki")}
    _, _, _, design, law, model = TUNING_GRIDS[name]
    return law(model(env), design(env, config)), info
