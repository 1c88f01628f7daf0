"""The plant: one vehicle, its integrator and its per-episode physics, as pure functions.

    plant = Plant("bluerov2_heavy", PlantConfig())
    params = plant.sample_params(key)                 # PlantParams of one episode (explicit pytree)
    state = plant.init(key, params, start)            # PlantState: MJX data, thruster lag, current
    state, finite = plant.step(params, state, action, key)
    vs = plant.vehicle_state(state)                   # exact VehicleState (world pose, body velocities)

Everything an env, a controller, an identification routine or an export needs from the physics
goes through this layer; envs add tasks (targets, observations, rewards) on top.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct
from mujoco import mjx

from marinejax.errors import UserError
from marinejax.frames import quat_to_mat
from marinejax.physics import (
    COMMAND_MODES,
    PhysicsState,
    VehicleState,
    check_integrator,
    control_step,
    from_physics,
    to_physics,
    with_timestep,
)
from marinejax.plant.current import CurrentConfig, CurrentState, sample_current, step_current
from marinejax.plant.disturbance import DisturbanceConfig, body_wrench, sample_disturbance
from marinejax.plant.params import PlantParams, apply_params, nominal_params
from marinejax.plant.randomization import RandomizationConfig, sample_dynamics
from marinejax.plant.rays import SceneRays
from marinejax.plant.scene_sensors import SceneSensors
from marinejax.plant.sensors import SensorConfig, SensorSuite
from marinejax.scene import DEFAULT_SCENE, LATCH as SCENE_LATCH, PREFIX as SCENE_PREFIX, scene_path
from marinejax.vehicle import Vehicle, load_vehicle


@dataclasses.dataclass(frozen=True)
class PlantConfig:
    """How a vehicle is simulated and what varies per episode. Times in s."""

    param_set: str | None = None  # vehicle parameter set (None: the vehicle's default)
    scene: str = DEFAULT_SCENE  # the world the vehicle is in: a name of marinejax.scene.list_scenes() or an MJCF path
    control_dt: float = 0.05  # s per action (20 Hz)
    substeps: int = 1  # physics steps per action (50 ms with the second-order midpoint integrator)
    integrator: str = "midpoint"  # "midpoint" (second order) or "euler" (first order, needs <= 0.02 s steps)
    action_mode: str = "thrusters"  # thrusters: throttles in [−1, 1]; wrench: body wrench / wrench_scale
    wrench_scale: tuple[float, float, float, float, float, float] = (80.0, 80.0, 100.0, 15.0, 15.0, 15.0)  # N, N m
    current: CurrentConfig = CurrentConfig()
    randomization: RandomizationConfig = RandomizationConfig()
    disturbance: DisturbanceConfig = DisturbanceConfig()
    sensors: SensorConfig = SensorConfig()  # read by envs in observation_mode "sensors"; altimeter and sonar in any mode
    # names (without "scene:") of scene geoms on the world body that an env places per episode (PlantParams.layout)
    movable_geoms: tuple[str, ...] = dataclasses.field(default=(), metadata={"variable_length": True})

    def __post_init__(self):
        scene_path(self.scene)  # an unknown scene is named with the valid ones here, not at the first reset
        if self.action_mode not in COMMAND_MODES:
            raise UserError(f"config 'action_mode' must be one of {list(COMMAND_MODES)}, got {self.action_mode!r}")
        if not self.control_dt > 0:
            raise UserError(f"config 'control_dt' must be > 0, got {self.control_dt}")
        if self.substeps < 1:
            raise UserError(f"config 'substeps' must be >= 1, got {self.substeps}")
        check_integrator(self.integrator, self.control_dt / self.substeps)
        if any(s <= 0 for s in self.wrench_scale):
            raise UserError(f"config 'wrench_scale' must be positive, got {self.wrench_scale}")


@struct.dataclass
class PlantState:
    """What the plant carries between control steps."""

    physics: PhysicsState  # MJX data (free joint of the vehicle) and the lagged thruster forces
    current: CurrentState  # ocean current, world frame, m/s


class Plant:
    """A vehicle simulated at `config.control_dt` per action. Names, sizes and the MJX model are
    resolved here, once; every method is pure and jit/vmap-able."""

    def __init__(self, vehicle: str | Vehicle, config: PlantConfig = PlantConfig()):
        self.config = config
        if isinstance(vehicle, Vehicle) and vehicle.scene != str(config.scene):
            raise UserError(f"vehicle {vehicle.name!r} was loaded in scene {vehicle.scene!r} but the config asks for "
                            f"{config.scene!r}; load it with load_vehicle(..., scene={config.scene!r}) or pass its name")
        self.vehicle = vehicle if isinstance(vehicle, Vehicle) else load_vehicle(vehicle, param_set=config.param_set, scene=config.scene)
        self.sys = with_timestep(self.vehicle.sys, config.control_dt / config.substeps).replace(layout_ids=self._movable(config.movable_geoms))
        self.gravity = float(-self.vehicle.mj_model.opt.gravity[2])  # m/s^2
        self.action_size = self.vehicle.num_actuators if config.action_mode == "thrusters" else 6
        self._wrench_scale = jnp.asarray(np.asarray(config.wrench_scale, np.float32))
        self.sensors = SensorSuite(config.sensors, config.control_dt, self.gravity)
        self.rays = SceneRays(self.vehicle.mj_model, self.sys.body_id, self.sys.layout_ids)
        self.scene_sensors = SceneSensors(config.sensors, config.control_dt)  # the enabled altimeter and sonar
        if self.rays.meshes and any(getattr(s, "incidence", False) for s in self.scene_sensors.sensors.values()):
            raise UserError(f"scene {self.vehicle.scene!r} has meshes among the geoms the rays see; the sonar's echo intensity "
                            "(config 'sensors.sonar.intensity') needs primitive geoms (planes, spheres, capsules, ellipsoids, boxes)")
        m = self.vehicle.mj_model
        self.latch_id = next((i for i in range(m.neq) if m.eq(i).name == SCENE_LATCH), None)  # the scene's latch weld (marinejax.scene)
        # The MJX step is traced once per plant and reused wherever it is called (training rollout,
        # evaluation, tests): inlined into each caller's jit it is retraced by each, seconds apiece.
        self._step = jax.jit(self._step_unjitted)

    def _movable(self, names: tuple[str, ...]) -> tuple[int, ...]:
        m = self.vehicle.mj_model
        scene = sorted(m.geom(i).name[len(SCENE_PREFIX):] for i in range(m.ngeom)
                       if m.geom(i).name.startswith(SCENE_PREFIX) and m.geom_bodyid[i] == 0)
        for name in names:
            if name not in scene:
                raise UserError(f"config 'movable_geoms': scene {self.vehicle.scene!r} has no geom {name!r} on its world body; "
                                f"valid: {scene}")
        return tuple(m.geom(SCENE_PREFIX + name).id for name in names)

    def nominal_params(self) -> PlantParams:
        """The vehicle's parameters as loaded, no disturbance."""
        return nominal_params(self.sys)

    def sample_params(self, rng: jax.Array) -> PlantParams:
        """One episode's parameters: randomized when `randomization.enabled`, with a disturbance
        drawn when `disturbance.enabled` (else the nominal parameters and no disturbance)."""
        k_dyn, k_dist = jax.random.split(rng)
        cfg = self.config
        params = self.nominal_params()
        if cfg.randomization.enabled:
            kinds = tuple(g.kind for g in self.sys.actuators)
            params = sample_dynamics(k_dyn, params, kinds, self.gravity, cfg.randomization)
        return params.replace(disturbance=sample_disturbance(k_dist, cfg.disturbance))

    def init(self, rng: jax.Array, params: PlantParams, start: VehicleState) -> PlantState:
        """The plant at `start` (world pose, body velocities, thrust), with this episode's current."""
        physics = to_physics(apply_params(self.sys, params), start)
        return PlantState(physics=physics, current=sample_current(rng, self.config.current))

    def step(self, params: PlantParams, state: PlantState, action: jax.Array, rng: jax.Array) -> tuple[PlantState, jax.Array]:
        """One control step under `action` (clipped to [−1, 1]: throttles, or the body wrench divided
        by `wrench_scale`). Returns (new state, finite): a non-finite result is never propagated,
        the last finite physics state is kept and `finite` is False."""
        if jnp.shape(action) != (self.action_size,):
            raise UserError(f"action must have shape ({self.action_size},) ({self.config.action_mode} mode), got {jnp.shape(action)}")
        return self._step(params, state, action, rng)

    def _step_unjitted(self, params: PlantParams, state: PlantState, action: jax.Array, rng: jax.Array) -> tuple[PlantState, jax.Array]:
        cfg = self.config
        action = jnp.clip(action, -1.0, 1.0)
        current = step_current(state.current, rng, cfg.control_dt, cfg.current)
        sys = apply_params(self.sys, params)
        command = action if cfg.action_mode == "thrusters" else action * self._wrench_scale
        external = None
        if cfg.disturbance.enabled:
            external = body_wrench(params.disturbance, quat_to_mat(self.vehicle_state(state).quaternion))
        ps = control_step(sys, state.physics, command, current.value, cfg.substeps, cfg.action_mode, cfg.integrator, external)
        finite = jnp.all(jnp.isfinite(ps.data.qpos)) & jnp.all(jnp.isfinite(ps.data.qvel)) & jnp.all(jnp.isfinite(ps.actuators))
        ps = jax.tree.map(lambda new, old: jnp.where(finite, new, old), ps, state.physics)
        return PlantState(physics=ps, current=current), finite

    def open_loop(self, params: PlantParams, state: PlantState, actions: jax.Array,
                  rng: jax.Array) -> tuple[PlantState, VehicleState, jax.Array]:
        """Run the actions (T, action_size) one control step each. Returns the final state, the
        exact `VehicleState` after every step (leaves with a leading axis T) and `finite` (T,)."""

        def body(state, xs):
            action, key = xs
            state, finite = self.step(params, state, action, key)
            return state, (self.vehicle_state(state), finite)

        final, (states, finite) = jax.lax.scan(body, state, (actions, jax.random.split(rng, actions.shape[0])))
        return final, states, finite

    def vehicle_state(self, state: PlantState) -> VehicleState:
        """The exact kinematic state: world position and quaternion, body-frame velocities, thrust."""
        return from_physics(self.sys, state.physics)

    def world(self, params: PlantParams, state: PlantState) -> tuple[mjx.Model, mjx.Data]:
        """The scene as it is now, for sensors and tasks that see it: the MJX model of this episode
        (its layout placed) and data with every body's and geom's world pose computed at the current
        state (`mjx.kinematics`)."""
        model = apply_params(self.sys, params).model
        return model, mjx.kinematics(model, state.physics.data)

    def cast(self, params: PlantParams, state: PlantState):
        """The ray cast of the vehicle at `state` into its scene, for the scene sensors:
        cast(mount (3, m, body), directions (..., 3, unit, body), max_range (m), incidence=False) →
        (range (...,) m, hit (...,) bool[, cosine of the incidence angle (...,)]), as `SceneRays.cast`."""
        vs = self.vehicle_state(state)
        return lambda mount, directions, max_range, incidence=False: self.rays.cast(params.layout, state.physics.data, vs, mount,
                                                                                    directions, max_range, incidence)

    def latch(self, state: PlantState, closed: jax.Array) -> PlantState:
        """The state with the scene's latch (marinejax.scene) closed where `closed` (bool, ()) is
        true, open where false, from the next physics step on: closed, it holds the vehicle's nose on
        the dock's seat."""
        if self.latch_id is None:
            raise UserError(f"scene {self.vehicle.scene!r} has no latch for vehicle {self.vehicle.name!r} (a scene site "
                            f"{SCENE_LATCH!r} and a vehicle site 'nose'; marinejax.scene)")
        data = state.physics.data
        data = data.replace(eq_active=data.eq_active.at[self.latch_id].set(closed))
        return state.replace(physics=state.physics.replace(data=data))

    def contact_wrench(self, state: PlantState) -> jnp.ndarray:
        """What the scene's contacts exert on the vehicle (6,): force (N, world frame) and moment about
        the CG (N m, body frame FLU), from MuJoCo's constraint solution at the last physics step
        (zeros where the scene has no contacts); a closed latch's hold is included."""
        if not self.sys.contacts:
            return jnp.zeros(6)
        da = self.sys.dof_adr
        return state.physics.data.qfrc_constraint[da : da + 6]

    def privileged(self, params: PlantParams, state: PlantState) -> jnp.ndarray:
        """What a real vehicle cannot measure, as one vector for a critic (body frame FLU):
        current (3, m/s), disturbance force (3, N) and torque (3, N m), mass (kg), net buoyancy (N),
        inertia (3), added mass (6), linear and quadratic damping (6 + 6), centre of buoyancy (3, m),
        then each actuator group's episode parameters (`ActuatorKind.privileged`; T200s: gains (N),
        time constant (s), supply voltage (V))."""
        rot = quat_to_mat(self.vehicle_state(state).quaternion)
        h = params.hydro
        return jnp.concatenate([
            rot.T @ state.current.value,
            body_wrench(params.disturbance, rot),
            params.mass[None], params.net_buoyancy(self.gravity)[None], params.inertia,
            h.added_mass, h.linear_damping, h.quadratic_damping, h.center_of_buoyancy,
            *(g.kind.privileged(p) for g, p in zip(self.sys.actuators, params.actuators)),
        ])

