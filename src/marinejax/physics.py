"""The physics step: MJX integrates the rigid body, marinejax.hydro supplies the fluid wrench and the
vehicle's actuators (`marinejax.actuators`) their wrench, through `data.xfrc_applied` at every
substep; plus a batched open-loop rollout.

Integrators (`integrator=`), both with one MJX evaluation per physics step of h = model.opt.timestep:
- "midpoint" (default), second order: a cheap predictor (the full acceleration from
  `hydro_terms`) takes the state and the actuator states to t + h/2; there the fluid and actuator
  wrench is evaluated and `mjx.forward` gives the acceleration of the whole model; the step then
  uses the midpoint velocity and acceleration (explicit midpoint rule, the free joint's quaternion
  advanced by the exact exponential). Error falls 4× when h halves; stable up to 0.05 s.
- "euler", first order: the wrench at the start of the step and `mjx.step` (MuJoCo's
  semi-implicit Euler). Kept for comparison; needs h ≤ 0.02 s and about 5× more steps for the
  same accuracy.
A vehicle is one free body (its free joint at `sys.qpos_adr` / `sys.dof_adr`).

In a scene with contacts (`sys.contacts`, `marinejax.scene`) a contact force must act on the
rigid-plus-added inertia, as the water around the vehicle is accelerated with it. There the added
mass goes into MuJoCo's mass matrix (Jᵀ M_A J at the free joint, J = diag(Rᵀ, I) maps MuJoCo's
velocities to ν) after `mjx.fwd_position`, and the fluid wrench handed to MuJoCo is
τ_other − M_A b, b = [−ω × v, 0] being the part of ν̇ that MuJoCo's world-frame linear velocity does
not carry; MuJoCo's constraint solver then sees the whole inertia. In open water the two
formulations give the same motion (to float rounding, tested); the cheaper one, the added mass
inside the applied wrench, is used there.

State conventions: position (m) and quaternion (w, x, y, z, body→world) in the world frame (z up);
linear (m/s) and angular (rad/s) velocity in the body frame FLU; actuator states in each kind's
physical unit (a T200's thrust in N), in action order.
"""

from __future__ import annotations

import functools
from typing import Literal

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct
from mujoco import mjx

import marinejax.actuators as actuators
from marinejax.errors import UserError
from marinejax.frames import quat_integrate, quat_to_mat
from marinejax.hydro.forces import added_mass_at_cg, hydro_terms
from marinejax.vehicle import Vehicle, VehicleSystem, mjx_device

CommandMode = Literal["thrusters", "wrench"]
COMMAND_MODES = ("thrusters", "wrench")
Integrator = Literal["midpoint", "euler"]
INTEGRATORS = ("midpoint", "euler")
# Largest physics step (s) per integrator: midpoint is checked stable at 0.05 s on both vehicles at
# full thrust (tests/test_physics.py); semi-implicit Euler is limited by the quadratic damping.
MAX_TIMESTEP = {"midpoint": 0.05, "euler": 0.02}
DEFAULT_INTEGRATOR: Integrator = "midpoint"


def check_integrator(integrator: str, timestep: float) -> None:
    """Raise ValueError for an unknown integrator or a physics step (s) beyond its stable limit."""
    if integrator not in INTEGRATORS:
        raise UserError(f"unknown integrator {integrator!r}; valid: {list(INTEGRATORS)}")
    if not timestep <= MAX_TIMESTEP[integrator] + 1e-12:
        raise UserError(
            f"physics step {timestep:.4f} s exceeds {MAX_TIMESTEP[integrator]} s, the stable limit of the "
            f"{integrator!r} integrator; use more substeps"
        )


class SimulationDiverged(FloatingPointError):
    """The simulation produced a non-finite state."""


@struct.dataclass
class VehicleState:
    """Kinematic state of one vehicle (leaves may carry leading batch axes)."""

    position: jnp.ndarray  # (3,) m, world frame, centre of gravity
    quaternion: jnp.ndarray  # (4,) w, x, y, z, body → world
    velocity: jnp.ndarray  # (3,) m/s, body frame FLU
    angular_velocity: jnp.ndarray  # (3,) rad/s, body frame FLU
    actuators: jnp.ndarray  # (N,) actuator states in action order (a T200's thrust in N)

    @property
    def thrust(self) -> jnp.ndarray:
        """The actuator states; on a thruster-driven vehicle, the thrust of each thruster (N)."""
        return self.actuators


@struct.dataclass
class PhysicsState:
    """What the physics step carries: the MJX data and the actuator states."""

    data: mjx.Data
    actuators: jnp.ndarray  # (N,) in each kind's physical unit


@struct.dataclass
class Trajectory:
    """Per control step, after the step (leading axes: [batch,] time)."""

    time: jnp.ndarray  # (T,) s, end of each control step
    position: jnp.ndarray  # (..., T, 3) m, world
    quaternion: jnp.ndarray  # (..., T, 4) w, x, y, z
    velocity: jnp.ndarray  # (..., T, 3) m/s, body FLU
    angular_velocity: jnp.ndarray  # (..., T, 3) rad/s, body FLU
    actuators: jnp.ndarray  # (..., T, N) actuator states (a T200's thrust in N)

    @property
    def thrust(self) -> jnp.ndarray:
        """The actuator states; on a thruster-driven vehicle, the thrust of each thruster (N)."""
        return self.actuators


def initial_state(
    vehicle: Vehicle,
    position=(0.0, 0.0, 0.0),
    quaternion=(1.0, 0.0, 0.0, 0.0),
    velocity=(0.0, 0.0, 0.0),
    angular_velocity=(0.0, 0.0, 0.0),
    actuators=None,
) -> VehicleState:
    """A VehicleState (at rest at the origin, level, facing +x, actuators at 0, by default).
    Quaternion is normalised."""
    q = jnp.asarray(quaternion, dtype=jnp.float32)
    return VehicleState(
        position=jnp.asarray(position, dtype=jnp.float32),
        quaternion=q / jnp.linalg.norm(q, axis=-1, keepdims=True),
        velocity=jnp.asarray(velocity, dtype=jnp.float32),
        angular_velocity=jnp.asarray(angular_velocity, dtype=jnp.float32),
        actuators=jnp.zeros(vehicle.num_actuators) if actuators is None else jnp.asarray(actuators, dtype=jnp.float32),
    )


def to_physics(sys: VehicleSystem, state: VehicleState) -> PhysicsState:
    """MJX data for a VehicleState (single vehicle; vmap for batches)."""
    data = mjx.make_data(sys.model, device=mjx_device())
    rot = quat_to_mat(state.quaternion)
    qa, da = sys.qpos_adr, sys.dof_adr
    qpos = data.qpos.at[qa : qa + 3].set(state.position).at[qa + 3 : qa + 7].set(state.quaternion)
    qvel = data.qvel.at[da : da + 3].set(rot @ state.velocity).at[da + 3 : da + 6].set(state.angular_velocity)
    return PhysicsState(data=data.replace(qpos=qpos, qvel=qvel), actuators=state.actuators)


def from_physics(sys: VehicleSystem, ps: PhysicsState) -> VehicleState:
    """VehicleState of the physics state (body-frame velocities from MJX's world-frame linear velocity)."""
    qa, da = sys.qpos_adr, sys.dof_adr
    quat = ps.data.qpos[qa + 3 : qa + 7]
    rot = quat_to_mat(quat)
    return VehicleState(
        position=ps.data.qpos[qa : qa + 3],
        quaternion=quat,
        velocity=rot.T @ ps.data.qvel[da : da + 3],
        angular_velocity=ps.data.qvel[da + 3 : da + 6],
        actuators=ps.actuators,
    )


def model_acceleration(sys: VehicleSystem, qpos: jnp.ndarray, qvel: jnp.ndarray, actuator_state: jnp.ndarray,
                       wrench: jnp.ndarray, current_world: jnp.ndarray):
    """Fluid and actuator wrench and the resulting acceleration at MJX coordinates (qpos, qvel).

    actuator_state: (N,) in action order; wrench: (6,) extra body wrench [N, N m]; current_world:
    (3,) m/s.
    Returns (xfrc (6,): the wrench for `data.xfrc_applied`, world frame [force, torque] at the CG;
    qacc (6,): the free joint's acceleration [d/dt of the world-frame velocity (m/s²), body-frame
    angular acceleration (rad/s²)], as MuJoCo's forward dynamics gives it under that wrench).
    """
    terms, rot, nu = _hydro(sys, qpos, qvel, actuator_state, wrench, current_world)
    xfrc = jnp.concatenate([rot @ terms.applied_wrench[:3], rot @ terms.applied_wrench[3:]])
    acc = terms.acceleration
    qacc = jnp.concatenate([rot @ (acc[:3] + jnp.cross(nu[3:], nu[:3])), acc[3:]])
    return xfrc, qacc


def _hydro(sys: VehicleSystem, qpos, qvel, actuator_state, wrench, current_world):
    """(HydroTerms, body-to-world rotation, ν) at MJX coordinates (qpos, qvel)."""
    model = sys.model
    qa, da = sys.qpos_adr, sys.dof_adr
    rot = quat_to_mat(qpos[qa + 3 : qa + 7])
    nu = jnp.concatenate([rot.T @ qvel[da : da + 3], qvel[da + 3 : da + 6]])
    nu_r = nu - jnp.concatenate([rot.T @ current_world, jnp.zeros(3)])
    terms = hydro_terms(
        sys.hydro,
        model.body_mass[sys.body_id],
        model.body_inertia[sys.body_id],
        rot,
        nu,
        actuators.wrench(sys.actuators, actuator_state, nu_r) + wrench,
        current_world,
        -model.opt.gravity[2],
    )
    return terms, rot, nu


def contact_inputs(sys: VehicleSystem, qpos, qvel, actuator_state, wrench, current_world):
    """For a scene with contacts (see the module docstring): (xfrc (6,), world [force, torque] at the
    CG: the fluid and actuator wrench without the added-mass inertia; added (6, 6): the added mass
    in MuJoCo's coordinates of the free joint, to add to its mass matrix)."""
    terms, rot, nu = _hydro(sys, qpos, qvel, actuator_state, wrench, current_world)
    m_a = added_mass_at_cg(sys.hydro)
    body = terms.other_wrench - m_a @ jnp.concatenate([-jnp.cross(nu[3:], nu[:3]), jnp.zeros(3)])
    xfrc = jnp.concatenate([rot @ body[:3], rot @ body[3:]])
    added = jnp.block([[rot @ m_a[:3, :3] @ rot.T, rot @ m_a[:3, 3:]], [m_a[3:, :3] @ rot.T, m_a[3:, 3:]]])
    return xfrc, added


def forward_with_added_mass(sys: VehicleSystem, data: mjx.Data, added: jnp.ndarray) -> mjx.Data:
    """`mjx.forward` with `added` (6, 6) added to the free joint's block of the mass matrix before the
    smooth and constraint accelerations are solved (contacts then act on the whole inertia).
    MJX keeps the dense mass matrix in `data._impl.M` (its own deprecation notice names that path)."""
    model, da = sys.model, sys.dof_adr
    d = mjx.fwd_position(model, data)
    d = d.tree_replace({"_impl.M": d._impl.M.at[da : da + 6, da : da + 6].add(added)})
    d = mjx.factor_m(model, d)
    d = mjx.fwd_velocity(model, d)
    d = mjx.fwd_actuation(model, d)
    d = mjx.fwd_acceleration(model, d)
    if d._impl.efc_J.size == 0:
        return d.replace(qacc=d.qacc_smooth)
    return mjx.solve(model, d)


def _forward_in_scene(sys: VehicleSystem, data: mjx.Data, qpos, qvel, actuator_state, wrench, current_world) -> mjx.Data:
    """MJX's forward dynamics with contacts at (qpos, qvel): the fluid and actuator wrench of
    `contact_inputs` applied, the added mass in the mass matrix (`forward_with_added_mass`)."""
    xfrc, added = contact_inputs(sys, qpos, qvel, actuator_state, wrench, current_world)
    return forward_with_added_mass(sys, data.replace(qpos=qpos, qvel=qvel, xfrc_applied=data.xfrc_applied.at[sys.body_id].set(xfrc)), added)


def _advance_free_joint(sys: VehicleSystem, qpos: jnp.ndarray, qvel: jnp.ndarray, dt) -> jnp.ndarray:
    """qpos after moving the free joint for dt (s) at constant qvel (world velocity, body rates)."""
    qa, da = sys.qpos_adr, sys.dof_adr
    pos = qpos[qa : qa + 3] + dt * qvel[da : da + 3]
    quat = quat_integrate(qpos[qa + 3 : qa + 7], qvel[da + 3 : da + 6], dt)
    return qpos.at[qa : qa + 3].set(pos).at[qa + 3 : qa + 7].set(quat)


def substep(
    sys: VehicleSystem,
    ps: PhysicsState,
    target: jnp.ndarray,
    wrench: jnp.ndarray,
    current_world: jnp.ndarray,
    integrator: Integrator = DEFAULT_INTEGRATOR,
) -> PhysicsState:
    """One physics step of h = sys.model.opt.timestep: the actuator states move towards `target`
    ((N,), by each kind's own dynamics, e.g. a thruster's exact first-order lag), the body wrench
    `wrench` (6,) is added, and the model is integrated by `integrator` (see the module docstring)."""
    model, data = sys.model, ps.data
    h = model.opt.timestep
    groups = sys.actuators
    if integrator == "euler":
        state = actuators.advance(groups, ps.actuators, target, h)
        if sys.contacts:
            data = _forward_in_scene(sys, data, data.qpos, data.qvel, state, wrench, current_world)
            return PhysicsState(data=mjx.euler(model, data), actuators=state)
        xfrc, _ = model_acceleration(sys, data.qpos, data.qvel, state, wrench, current_world)
        data = data.replace(xfrc_applied=data.xfrc_applied.at[sys.body_id].set(xfrc))
        return PhysicsState(data=mjx.step(model, data), actuators=state)
    if integrator != "midpoint":
        raise UserError(f"unknown integrator {integrator!r}; valid: {list(INTEGRATORS)}")
    # Predictor: the state at t + h/2 from the acceleration at t (hydro_terms holds the whole model,
    # contacts excepted).
    _, qacc0 = model_acceleration(sys, data.qpos, data.qvel, ps.actuators, wrench, current_world)
    qpos_mid = _advance_free_joint(sys, data.qpos, data.qvel, h / 2)
    qvel_mid = data.qvel + (h / 2) * qacc0
    actuators_mid = actuators.advance(groups, ps.actuators, target, h / 2)
    # Midpoint: fluid and actuator wrench there, rigid-body dynamics (and contacts) by MuJoCo.
    if sys.contacts:
        mid = _forward_in_scene(sys, data, qpos_mid, qvel_mid, actuators_mid, wrench, current_world)
    else:
        xfrc, _ = model_acceleration(sys, qpos_mid, qvel_mid, actuators_mid, wrench, current_world)
        mid = mjx.forward(model, data.replace(qpos=qpos_mid, qvel=qvel_mid, xfrc_applied=data.xfrc_applied.at[sys.body_id].set(xfrc)))
    data = mid.replace(
        qpos=_advance_free_joint(sys, data.qpos, qvel_mid, h),
        qvel=data.qvel + h * mid.qacc,
        time=data.time + h,
    )
    return PhysicsState(data=data, actuators=actuators.advance(groups, ps.actuators, target, h))


def with_timestep(sys: VehicleSystem, dt) -> VehicleSystem:
    """Copy of sys whose MJX model integrates with physics step dt (s)."""
    return sys.replace(model=sys.model.replace(opt=sys.model.opt.replace(timestep=jnp.asarray(dt, jnp.float32))))


def control_step(
    sys: VehicleSystem,
    ps: PhysicsState,
    command: jnp.ndarray,
    current_world: jnp.ndarray,
    substeps: int,
    mode: CommandMode = "thrusters",
    integrator: Integrator = DEFAULT_INTEGRATOR,
    external: jnp.ndarray | None = None,
) -> PhysicsState:
    """Hold `command` for `substeps` physics steps of sys.model.opt.timestep each, integrated by
    `integrator` ("midpoint" or "euler", see the module docstring).

    mode "thrusters": command (N,) actuator commands in [−1, 1] (clipped), through the vehicle's
    actuators (`marinejax.actuators`; for T200s, throttles through the thrust curve and lag).
    mode "wrench": command (6,) body wrench [N, N m], body frame FLU, applied directly.
    current_world: (3,) m/s ocean current, world frame, constant over the control step.
    external: optional (6,) body wrench [N, N m] added in either mode (e.g. a disturbance).
    """
    if mode == "thrusters":
        target = actuators.targets(sys.actuators, command)
        wrench = jnp.zeros(6)
    elif mode == "wrench":
        target, wrench = jnp.zeros_like(ps.actuators), command
    else:
        raise UserError(f"unknown command mode {mode!r}; valid: {list(COMMAND_MODES)}")
    if external is not None:
        wrench = wrench + external

    def body(p, _):
        return substep(sys, p, target, wrench, current_world, integrator), None

    ps, _ = jax.lax.scan(body, ps, None, length=substeps)
    return ps


@functools.partial(jax.jit, static_argnames=("substeps", "mode", "batched", "integrator"))
def rollout_batch(sys, state, commands, currents, control_dt, substeps, mode, batched, integrator=DEFAULT_INTEGRATOR):
    """The jitted core of `rollout` on validated arrays: `state` a VehicleState (batched if `batched`),
    commands (T, n) or (B, T, n), currents (T, 3) or (B, T, 3) in m/s, world. Returns the
    VehicleState after every control step, time (and batch) leading."""
    sys = with_timestep(sys, control_dt / substeps)

    def single(state, commands, currents):
        def body(ps, inputs):
            ps = control_step(sys, ps, inputs[0], inputs[1], substeps, mode, integrator)
            return ps, from_physics(sys, ps)

        _, states = jax.lax.scan(body, to_physics(sys, state), (commands, currents))
        return states

    if batched:
        return jax.vmap(single)(state, commands, currents)
    return single(state, commands, currents)


def rollout(
    vehicle: Vehicle,
    commands,
    initial: VehicleState | None = None,
    *,
    control_dt: float = 0.05,
    substeps: int = 1,
    mode: CommandMode = "thrusters",
    integrator: Integrator = DEFAULT_INTEGRATOR,
    current=None,
    sys: VehicleSystem | None = None,
    check_finite: bool = True,
) -> Trajectory:
    """Roll out one vehicle or a batch under a sequence of commands (jit-compiled once per shape).

    commands: (T, n) for one vehicle or (B, T, n) for a batch; n = number of actuators (mode
        "thrusters": actuator commands in [−1, 1], `vehicle.describe_action()`; a T200's throttle)
        or 6 (mode "wrench", body wrench in N and N m, FLU).
    initial: VehicleState, unbatched (shared by the whole batch) or with leading axis B; default at
        rest at the origin.
    control_dt: s per command; each is held for `substeps` physics steps of control_dt/substeps.
    integrator: "midpoint" (second order, default) or "euler" (first order, MuJoCo's own step).
    current: ocean current in m/s, world frame: None (still water), (3,) constant, or (T, 3) /
        (B, T, 3) per control step.
    sys: parameters to simulate instead of vehicle.sys (e.g. modified HydroParams).
    Returns the state after each control step. Raises SimulationDiverged on a non-finite state.
    """
    if mode not in COMMAND_MODES:
        raise UserError(f"unknown command mode {mode!r}; valid: {list(COMMAND_MODES)}")
    if not (isinstance(substeps, int) and substeps >= 1):
        raise UserError(f"substeps must be a positive integer, got {substeps!r}")
    if not (np.isfinite(control_dt) and control_dt > 0):
        raise UserError(f"control_dt must be a positive number of seconds, got {control_dt!r}")
    check_integrator(integrator, control_dt / substeps)
    commands = jnp.asarray(commands, dtype=jnp.float32)
    n = vehicle.num_actuators if mode == "thrusters" else 6
    what = f"{n} actuator commands for {vehicle.name}" if mode == "thrusters" else "a 6-component body wrench"
    if commands.ndim not in (2, 3) or commands.shape[-1] != n:
        raise UserError(f"commands must have shape (T, {n}) or (B, T, {n}) ({what}, mode {mode!r}); got {commands.shape}")
    if not bool(jnp.all(jnp.isfinite(commands))):
        raise UserError("commands contain non-finite values")
    batched = commands.ndim == 3
    lead = commands.shape[:-1]
    current = jnp.zeros(3) if current is None else jnp.asarray(current, dtype=jnp.float32)
    if current.shape == (3,):
        current = jnp.broadcast_to(current, lead + (3,))
    if current.shape != lead + (3,):
        raise UserError(f"current must have shape (3,) or {lead + (3,)}; got {current.shape}")
    state = initial_state(vehicle) if initial is None else initial
    if state.actuators.shape[-1] != vehicle.num_actuators:
        raise UserError(f"initial.actuators must have {vehicle.num_actuators} entries for {vehicle.name}; got {state.actuators.shape}")
    if batched and state.position.ndim == 1:
        state = jax.tree.map(lambda x: jnp.broadcast_to(x, (lead[0],) + x.shape), state)
    if state.position.shape[:-1] != lead[:-1]:
        raise UserError(f"initial state batch shape {state.position.shape[:-1]} does not match commands {lead[:-1]}")

    states = rollout_batch(sys or vehicle.sys, state, commands, current, jnp.float32(control_dt), substeps, mode, batched, integrator)
    traj = Trajectory(
        time=control_dt * jnp.arange(1, lead[-1] + 1),
        position=states.position,
        quaternion=states.quaternion,
        velocity=states.velocity,
        angular_velocity=states.angular_velocity,
        actuators=states.actuators,
    )
    if check_finite:
        check_trajectory_finite(traj)
    return traj


def check_trajectory_finite(traj: Trajectory) -> None:
    """Raise SimulationDiverged naming the first control step (and batch members) that went non-finite."""
    ok = np.ones(np.shape(traj.position)[:-1], dtype=bool)
    for leaf in (traj.position, traj.quaternion, traj.velocity, traj.angular_velocity, traj.actuators):
        ok &= np.all(np.isfinite(np.asarray(leaf)), axis=-1)
    if ok.all():
        return
    bad = np.argwhere(~ok)
    first = int(bad[:, -1].min())
    members = sorted({int(b[0]) for b in bad}) if ok.ndim == 2 else []
    where = f" in batch members {members[:10]}{'...' if len(members) > 10 else ''}" if members else ""
    raise SimulationDiverged(f"simulation went non-finite at control step {first} (t = {float(traj.time[first]):.3f} s){where}")
