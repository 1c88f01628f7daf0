"""Torpedo docking: the latch, the errors and reward once latched, and the line-of-sight autopilot
flying the REMUS 100 into the funnel dock."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import marinejax
from marinejax.controllers import TorpedoAutopilotConfig, torpedo_autopilot
from marinejax.envs import Docking, TorpedoDocking
from marinejax.envs.registry import register_task
from marinejax.errors import UserError
from marinejax.frames import quat_from_euler, quat_to_mat
from marinejax.physics import VehicleState
from marinejax.statistics import rollout_controller, summarize


@pytest.fixture(scope="module")
def env():
    return marinejax.make("Remus100-Docking")


def test_docking_is_one_task_name_with_a_class_per_vehicle_kind():
    assert isinstance(marinejax.make("Remus100-Docking"), TorpedoDocking)
    assert type(marinejax.make("BlueROV2-Docking")) is Docking
    assert marinejax.make("Remus100FourFin-DockingDisturbed").config.current.mode == "ou"
    with pytest.raises(UserError, match="'Docking' is already registered for vehicles of kind \\['torpedo'\\]"):
        register_task("Docking", TorpedoDocking)
    with pytest.raises(UserError, match="'start_distance'"):
        marinejax.make("Remus100-Docking", start_distance=(-5.0, 10.0))
    with pytest.raises(UserError, match="'nose' must be a sequence of 3 values"):
        marinejax.make("Remus100-Docking", nose=(0.8, 0.0))


def test_disturbed_docking_starts_bow_first_over_the_ground_not_crabbed():
    """Unlike the paths (`fit_start`), docking keeps the drawn start in a current: moving forward at
    the commanded speed over the ground, body frame."""
    env = marinejax.make("Remus100-DockingDisturbed")
    states = jax.vmap(env.reset)(jax.random.split(jax.random.PRNGKey(3), 8))
    vs = jax.vmap(env.plant.vehicle_state)(states.pipeline_state)
    assert np.linalg.norm(np.asarray(states.pipeline_state.current.value), axis=1).max() > 0.1
    speed = np.asarray(states.info["task"].speed)
    np.testing.assert_allclose(np.asarray(vs.velocity), np.stack([speed, 0 * speed, 0 * speed], axis=1), atol=1e-6)


def _at(env, nose_position, yaw=0.0, speed=1.0):
    """A vehicle state whose nose is at `nose_position` (m, world), level, at heading `yaw`, moving
    forward at `speed` (m/s)."""
    q = quat_from_euler(0.0, 0.0, yaw)
    cg = jnp.asarray(nose_position, jnp.float32) - quat_to_mat(q) @ jnp.asarray(env.config.nose, jnp.float32)
    return VehicleState(position=cg, quaternion=q, velocity=jnp.array([speed, 0.0, 0.0]), angular_velocity=jnp.zeros(3),
                        actuators=jnp.zeros(env.vehicle.num_actuators))


def test_the_latch_closes_on_a_nose_inside_the_tube_and_stays_closed(env):
    state = jax.jit(env.reset)(jax.random.PRNGKey(0))
    task, info = state.info["task"], state.info
    advance = jax.jit(env.advance_task)
    play = env.config.capture_radius
    for nose, docked in [((0.9, 0.0, 0.0), 0.0),  # before the tube's entrance
                         ((1.05, 0.0, play - 0.01), 1.0), ((1.05, play - 0.01, 0.0), 1.0),
                         ((1.05, 0.0, play + 0.02), 0.0),  # past the entrance, outside the ring of bars
                         ((5.0, 3.0, 0.0), 0.0)]:  # beside the dock
        assert float(advance(task, _at(env, nose), info).docked) == docked, nose
    assert float(advance(task, _at(env, (1.05, 0.0, 0.0), speed=-0.1), info).docked) == 0.0  # moving backwards
    latched = advance(task, _at(env, (1.05, 0.05, 0.0), yaw=0.1), {**info, "time": jnp.asarray(31.5)})
    assert float(latched.miss) == -1.0 and float(latched.latched) == 1.0
    np.testing.assert_allclose(latched.at_dock, [0.05, np.degrees(0.1), abs(float(task.speed) - float(latched.along_speed)), 31.5], rtol=1e-4)
    later = advance(latched, _at(env, (5.0, 3.0, 0.0)), {**info, "time": jnp.asarray(40.0)})
    assert float(later.docked) == 1.0 and np.array_equal(later.at_dock, latched.at_dock)  # held, wherever the vehicle goes on
    assert float(later.latched) == 0.0  # the latch closed one step earlier
    # passing the entrance's plane outside the tube is a miss, kept with its distance from the axis
    missed = advance(task, _at(env, (1.05, 3.0, 4.0)), info)
    assert float(missed.miss) == pytest.approx(5.0, rel=1e-5) and float(missed.docked) == 0.0
    after = advance(missed, _at(env, (1.5, 0.0, 0.0)), info)  # and nothing latches it afterwards
    assert float(after.docked) == 0.0 and float(after.miss) == pytest.approx(5.0, rel=1e-5)


def test_errors_measure_the_miss_and_keep_their_values_at_docking(env):
    state = jax.jit(env.reset)(jax.random.PRNGKey(0))
    info = {**state.info, "contact": jnp.array([0.0, 300.0, 400.0, 0.0, 0.0, 0.0])}
    errors = jax.jit(env.errors)
    free = errors(_at(env, (-3.0, 0.4, -0.3), yaw=0.5), info)
    assert float(free["position_error"]) == pytest.approx(np.hypot(4.0, 0.5), rel=1e-5)  # nose to (1, 0, 0)
    assert float(free["docked"]) == 0.0 and float(free["impact_force"]) == pytest.approx(500.0)
    assert not env.failed(free) and env.failed({**free, "impact_force": jnp.asarray(1000.5)})  # a crash
    assert env.failed({**free, "cross_track_error": jnp.asarray(10.5)})  # lost
    missed = {**info, "task": info["task"].replace(miss=jnp.asarray(0.7))}
    assert float(errors(_at(env, (30.0, 5.0, 0.0)), missed)["position_error"]) == pytest.approx(0.7)  # the miss, however far it flies on
    at_dock = jnp.array([0.03, 2.0, 0.1, 25.0])
    latched = {**info, "task": info["task"].replace(docked=jnp.ones(()), at_dock=at_dock)}
    after = errors(_at(env, (8.0, 2.0, 0.0), yaw=0.5), latched)
    assert {k: round(float(v), 5) for k, v in after.items()} == {
        "position_error": 0.0, "lateral_error": 0.03, "heading_error_deg": 2.0, "speed_error": 0.1, "time_to_dock": 25.0,
        "cross_track_error": 0.0, "impact_force": 0.0, "docked": 1.0}
    # once latched: the best value of every term, and the docking bonus only on the step the latch closes
    reward_terms = jax.jit(env.reward_terms)
    for latch_step in (1.0, 0.0):
        now = {**latched, "task": latched["task"].replace(latched=jnp.asarray(latch_step))}
        terms = reward_terms(_at(env, (8.0, 2.0, 0.0), yaw=0.5), now, jnp.ones(env.action_size))
        assert {k: float(v) for k, v in terms.items() if v != 0} == {"position": 1.0, "precision": 1.0, "speed": 1.0, "heading": 1.0,
                                                                     **({"docked": 1.0} if latch_step else {})}


def test_line_of_sight_flies_the_remus_into_the_dock(env):
    """The line-of-sight autopilot (Δ = 5 m, no tuning) on 4 episodes, 20-40 m out, up to 2 m off the
    axis: every one latched, the funnel's bars touched on the way in on some."""
    controller = torpedo_autopilot(env, TorpedoAutopilotConfig(heading_gain=5.0, heading_derivative_time=1.0, lookahead=5.0))
    result = rollout_controller(env, controller, 4, seed=3)
    stats = summarize(env, result)
    assert stats["success_rate"] == 1.0 and stats["position_error_mean_m"] == 0.0, stats
    assert stats["success_flag"] == "docked"  # the latch, the same episodes as the error below 0.1 m
    first = result["docked"].argmax(axis=1)
    assert (result["docked"].max(axis=1) == 1).all() and (first < env.config.episode_length - 10).all()
    # until latched, the nose's distance from the latch point falls as the vehicle closes in
    for e, k in enumerate(first):
        assert result["error"][e, 0] > 19.0 and result["error"][e, k - 1] < 1.0
        assert result["time_to_dock"][e, -1] == pytest.approx(result["time"][k], abs=1e-3)
    assert (result["lateral_error"][:, -1] <= env.config.capture_radius).all()
    assert np.isfinite(result["impact_force"]).all()
    # the dock's latch holds the docked vehicle: within 2 s its nose is on the seat (the scene's site
    # `latch`, on the axis 0.3 m inside the tube), and it stays there, aligned with the axis, to the episode's end
    for e, k in enumerate(first):
        rot = np.asarray(jax.vmap(quat_to_mat)(jnp.asarray(result["quaternion"][e, k + 20:])))
        nose = result["position"][e, k + 20:] + rot @ np.asarray(env.config.nose)
        assert np.abs(nose - [1.3, 0.0, 0.0]).max() < 0.02, (e, nose.min(axis=0), nose.max(axis=0))
        assert (rot[:, 0, 0] > np.cos(np.radians(2.0))).all() and rot[-1, 0, 0] > np.cos(np.radians(0.2))  # aligned with the dock's axis


def test_the_latch_holds_a_vehicle_against_full_thrust_and_an_open_one_lets_it_pass():
    """The scene's latch (a weld, marinejax.scene) at the plant: a REMUS entering the tube at 1.5 m/s,
    0.05 m off the axis, under full thrust for 10 s. Closed, it draws the nose onto the seat
    (1.3, 0, 0) and holds it there (within 1.5 cm after 2 s, 1 cm over the last 5 s), the hold's force balancing the propeller's thrust;
    open (as at every reset), the vehicle flies on through the tube."""
    from marinejax.plant import Plant, PlantConfig

    plant = Plant("remus100", PlantConfig(scene="torpedo_dock", control_dt=0.1, substeps=2))
    params = plant.nominal_params()
    nose = np.array([0.8, 0.0, 0.02])  # the vehicle's site 'nose', body frame
    start = VehicleState(position=jnp.asarray([1.05, 0.05, 0.0] - nose, jnp.float32), quaternion=jnp.array([1.0, 0, 0, 0]),
                         velocity=jnp.array([1.5, 0.0, 0.0]), angular_velocity=jnp.zeros(3), actuators=jnp.zeros(plant.action_size))
    full = jnp.zeros(plant.action_size).at[-1].set(1.0)  # the propeller's throttle (fins centred)
    run = jax.jit(lambda s: plant.open_loop(params, s, jnp.tile(full, (100, 1)), jax.random.PRNGKey(0)))
    initial = plant.init(jax.random.PRNGKey(0), params, start)
    assert not bool(initial.physics.data.eq_active[plant.latch_id])  # open at the start
    held, states, finite = run(plant.latch(initial, jnp.asarray(True)))
    assert bool(finite.all())
    noses = np.asarray(states.position) + nose
    assert np.abs(noses[20:] - [1.3, 0.0, 0.0]).max() < 0.015 and np.abs(noses[-50:] - [1.3, 0.0, 0.0]).max() < 0.01
    assert noses[:, 0].max() < 1.5
    propeller = plant.sys.actuators[-1]  # its shaft speed (rev/min) at the end, at standstill in the water
    thrust = float(propeller.kind.wrench(propeller.design, propeller.params, states.actuators[-1, -1:], jnp.zeros(6))[0])
    assert thrust > 50.0  # N, the hull's share of the bollard thrust at full throttle
    assert float(plant.contact_wrench(held)[0]) == pytest.approx(-thrust, rel=0.02)  # the hold balances the thrust
    free, states, _ = run(initial)
    assert float(states.position[-1, 0]) > 2.8 + 5.0  # through the open tube and on
    with pytest.raises(UserError, match="scene 'rov_dock' has no latch"):
        Plant("remus100", PlantConfig(scene="rov_dock")).latch(initial, jnp.asarray(True))
    with pytest.raises(UserError, match="needs a scene whose dock holds the vehicle"):
        marinejax.make("Remus100-Docking", scene="rov_dock")
