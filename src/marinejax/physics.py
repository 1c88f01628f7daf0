"""The physics step: MJX integrates the rigid body, marinejax.hydro supplies the fluid and thruster
wrench through `data.xfrc_applied` at every substep; plus a batched open-loop rollout.

State conventions: position (m) and quaternion (w, x, y, z, body→world) in the world frame (z up);
linear (m/s) and angular (rad/s) velocity in the body frame FLU; thrust (N) per thruster.
"""

from __future__ import annotations

import functools
from typing import Literal

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct
from mujoco import mjx

from marinejax.frames import quat_to_mat
from marinejax.hydro.forces import hydro_terms
from marinejax.thrusters import lag_step, t200_thrust
from marinejax.vehicle import Vehicle, VehicleSystem

CommandMode = Literal["thrusters", "wrench"]
COMMAND_MODES = ("thrusters", "wrench")


class SimulationDiverged(FloatingPointError):
    """The simulation produced a non-finite state."""


@struct.dataclass
class VehicleState:
    """Kinematic state of one vehicle (leaves may carry leading batch axes)."""

    position: jnp.ndarray  # (3,) m, world frame, centre of gravity
    quaternion: jnp.ndarray  # (4,) w, x, y, z, body → world
    velocity: jnp.ndarray  # (3,) m/s, body frame FLU
    angular_velocity: jnp.ndarray  # (3,) rad/s, body frame FLU
    thrust: jnp.ndarray  # (N,) N, thruster forces (state of the lag)


@struct.dataclass
class PhysicsState:
    """What the physics step carries: the MJX data and the lagged thruster forces."""

    data: mjx.Data
    thrust: jnp.ndarray  # (N,) N


@struct.dataclass
class Trajectory:
    """Per control step, after the step (leading axes: [batch,] time)."""

    time: jnp.ndarray  # (T,) s, end of each control step
    position: jnp.ndarray  # (..., T, 3) m, world
    quaternion: jnp.ndarray  # (..., T, 4) w, x, y, z
    velocity: jnp.ndarray  # (..., T, 3) m/s, body FLU
    angular_velocity: jnp.ndarray  # (..., T, 3) rad/s, body FLU
    thrust: jnp.ndarray  # (..., T, N) N


def initial_state(
    vehicle: Vehicle,
    position=(0.0, 0.0, 0.0),
    quaternion=(1.0, 0.0, 0.0, 0.0),
    velocity=(0.0, 0.0, 0.0),
    angular_velocity=(0.0, 0.0, 0.0),
    thrust=None,
) -> VehicleState:
    """A VehicleState (at rest at the origin, level, facing +x, by default). Quaternion is normalised."""
    q = jnp.asarray(quaternion, dtype=jnp.float32)
    return VehicleState(
        position=jnp.asarray(position, dtype=jnp.float32),
        quaternion=q / jnp.linalg.norm(q, axis=-1, keepdims=True),
        velocity=jnp.asarray(velocity, dtype=jnp.float32),
        angular_velocity=jnp.asarray(angular_velocity, dtype=jnp.float32),
        thrust=jnp.zeros(vehicle.num_thrusters) if thrust is None else jnp.asarray(thrust, dtype=jnp.float32),
    )


def to_physics(sys: VehicleSystem, state: VehicleState) -> PhysicsState:
    """MJX data for a VehicleState (single vehicle; vmap for batches)."""
    data = mjx.make_data(sys.model)
    rot = quat_to_mat(state.quaternion)
    qa, da = sys.qpos_adr, sys.dof_adr
    qpos = data.qpos.at[qa : qa + 3].set(state.position).at[qa + 3 : qa + 7].set(state.quaternion)
    qvel = data.qvel.at[da : da + 3].set(rot @ state.velocity).at[da + 3 : da + 6].set(state.angular_velocity)
    return PhysicsState(data=data.replace(qpos=qpos, qvel=qvel), thrust=state.thrust)


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
        thrust=ps.thrust,
    )


def body_velocity(sys: VehicleSystem, data: mjx.Data):
    """(rotation body→world (3, 3), ν = [v, ω] body frame (6,)) of the vehicle in `data`."""
    rot = quat_to_mat(data.qpos[sys.qpos_adr + 3 : sys.qpos_adr + 7])
    v = rot.T @ data.qvel[sys.dof_adr : sys.dof_adr + 3]
    return rot, jnp.concatenate([v, data.qvel[sys.dof_adr + 3 : sys.dof_adr + 6]])


def substep(
    sys: VehicleSystem,
    ps: PhysicsState,
    thrust_target: jnp.ndarray,
    wrench: jnp.ndarray,
    current_world: jnp.ndarray,
) -> PhysicsState:
    """One physics step of sys.model.opt.timestep: lag the thrust towards `thrust_target` (N, (N,)),
    add the body wrench `wrench` (6,), solve the hydrodynamics and integrate with MJX."""
    model = sys.model
    thrust = lag_step(ps.thrust, thrust_target, model.opt.timestep, sys.thrusters.time_constant)
    tau = sys.thrusters.allocation @ thrust + wrench
    rot, nu = body_velocity(sys, ps.data)
    terms = hydro_terms(
        sys.hydro,
        model.body_mass[sys.body_id],
        model.body_inertia[sys.body_id],
        rot,
        nu,
        tau,
        current_world,
        -model.opt.gravity[2],
    )
    world = jnp.concatenate([rot @ terms.applied_wrench[:3], rot @ terms.applied_wrench[3:]])
    data = ps.data.replace(xfrc_applied=ps.data.xfrc_applied.at[sys.body_id].set(world))
    return PhysicsState(data=mjx.step(model, data), thrust=thrust)


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
) -> PhysicsState:
    """Hold `command` for `substeps` physics steps of sys.model.opt.timestep each.

    mode "thrusters": command (N,) throttles in [−1, 1] (clipped), through the T200 curve and lag.
    mode "wrench": command (6,) body wrench [N, N m], body frame FLU, applied directly.
    current_world: (3,) m/s ocean current, world frame, constant over the control step.
    """
    if mode == "thrusters":
        thrusters = sys.thrusters
        target = thrusters.gain * t200_thrust(thrusters.curve, command, thrusters.voltage)
        wrench = jnp.zeros(6)
    elif mode == "wrench":
        target, wrench = jnp.zeros_like(ps.thrust), command
    else:
        raise ValueError(f"unknown command mode {mode!r}; valid: {list(COMMAND_MODES)}")

    def body(p, _):
        return substep(sys, p, target, wrench, current_world), None

    ps, _ = jax.lax.scan(body, ps, None, length=substeps)
    return ps


@functools.partial(jax.jit, static_argnames=("substeps", "mode", "batched"))
def _rollout(sys, state, commands, currents, control_dt, substeps, mode, batched):
    sys = with_timestep(sys, control_dt / substeps)

    def single(state, commands, currents):
        def body(ps, inputs):
            ps = control_step(sys, ps, inputs[0], inputs[1], substeps, mode)
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
    substeps: int = 5,
    mode: CommandMode = "thrusters",
    current=None,
    sys: VehicleSystem | None = None,
    check_finite: bool = True,
) -> Trajectory:
    """Roll out one vehicle or a batch under a sequence of commands (jit-compiled once per shape).

    commands: (T, n) for one vehicle or (B, T, n) for a batch; n = number of thrusters (mode
        "thrusters", throttles in [−1, 1]) or 6 (mode "wrench", body wrench in N and N m, FLU).
    initial: VehicleState, unbatched (shared by the whole batch) or with leading axis B; default at
        rest at the origin.
    control_dt: s per command; each is held for `substeps` physics steps of control_dt/substeps.
    current: ocean current in m/s, world frame: None (still water), (3,) constant, or (T, 3) /
        (B, T, 3) per control step.
    sys: parameters to simulate instead of vehicle.sys (e.g. modified HydroParams).
    Returns the state after each control step. Raises SimulationDiverged on a non-finite state.
    """
    if mode not in COMMAND_MODES:
        raise ValueError(f"unknown command mode {mode!r}; valid: {list(COMMAND_MODES)}")
    if not (isinstance(substeps, int) and substeps >= 1):
        raise ValueError(f"substeps must be a positive integer, got {substeps!r}")
    if not (np.isfinite(control_dt) and control_dt > 0):
        raise ValueError(f"control_dt must be a positive number of seconds, got {control_dt!r}")
    commands = jnp.asarray(commands, dtype=jnp.float32)
    n = vehicle.num_thrusters if mode == "thrusters" else 6
    what = f"{n} thruster throttles for {vehicle.name}" if mode == "thrusters" else "a 6-component body wrench"
    if commands.ndim not in (2, 3) or commands.shape[-1] != n:
        raise ValueError(f"commands must have shape (T, {n}) or (B, T, {n}) ({what}, mode {mode!r}); got {commands.shape}")
    if not bool(jnp.all(jnp.isfinite(commands))):
        raise ValueError("commands contain non-finite values")
    batched = commands.ndim == 3
    lead = commands.shape[:-1]
    current = jnp.zeros(3) if current is None else jnp.asarray(current, dtype=jnp.float32)
    if current.shape == (3,):
        current = jnp.broadcast_to(current, lead + (3,))
    if current.shape != lead + (3,):
        raise ValueError(f"current must have shape (3,) or {lead + (3,)}; got {current.shape}")
    state = initial_state(vehicle) if initial is None else initial
    if state.thrust.shape[-1] != vehicle.num_thrusters:
        raise ValueError(f"initial.thrust must have {vehicle.num_thrusters} entries for {vehicle.name}; got {state.thrust.shape}")
    if batched and state.position.ndim == 1:
        state = jax.tree.map(lambda x: jnp.broadcast_to(x, (lead[0],) + x.shape), state)
    if state.position.shape[:-1] != lead[:-1]:
        raise ValueError(f"initial state batch shape {state.position.shape[:-1]} does not match commands {lead[:-1]}")

    states = _rollout(sys or vehicle.sys, state, commands, current, jnp.float32(control_dt), substeps, mode, batched)
    traj = Trajectory(
        time=control_dt * jnp.arange(1, lead[-1] + 1),
        position=states.position,
        quaternion=states.quaternion,
        velocity=states.velocity,
        angular_velocity=states.angular_velocity,
        thrust=states.thrust,
    )
    if check_finite:
        check_trajectory_finite(traj)
    return traj


def check_trajectory_finite(traj: Trajectory) -> None:
    """Raise SimulationDiverged naming the first control step (and batch members) that went non-finite."""
    ok = np.ones(np.shape(traj.position)[:-1], dtype=bool)
    for leaf in (traj.position, traj.quaternion, traj.velocity, traj.angular_velocity, traj.thrust):
        ok &= np.all(np.isfinite(np.asarray(leaf)), axis=-1)
    if ok.all():
        return
    bad = np.argwhere(~ok)
    first = int(bad[:, -1].min())
    members = sorted({int(b[0]) for b in bad}) if ok.ndim == 2 else []
    where = f" in batch members {members[:10]}{'...' if len(members) > 10 else ''}" if members else ""
    raise SimulationDiverged(f"simulation went non-finite at control step {first} (t = {float(traj.time[first]):.3f} s){where}")
