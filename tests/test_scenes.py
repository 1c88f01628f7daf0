"""Scenes and contacts: a vehicle placed in a scene file, and contact forces that act on the
rigid-plus-added inertia, against closed forms and against MJX's own contact on a plain body."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from mujoco import mjx

from marinejax import physics
from marinejax.errors import MissingFileError, UserError
from marinejax.frames import quat_to_mat
from marinejax.scene import list_scenes
from marinejax.vehicle import load_vehicle

G = 9.81


def _run(vehicle, state, wrench, steps: int, dt: float, substeps: int, hydro):
    """States after each control step and the contact force on the free joint then (world force N,
    body torque N m: MuJoCo's qfrc_constraint), holding the body `wrench` (N, N m, FLU)."""
    sys = physics.with_timestep(vehicle.sys.replace(hydro=hydro), dt / substeps)

    @jax.jit
    def go(ps):
        def body(ps, _):
            ps = physics.control_step(sys, ps, wrench, jnp.zeros(3), substeps, mode="wrench")
            return ps, (physics.from_physics(sys, ps), ps.data.qfrc_constraint[sys.dof_adr : sys.dof_adr + 6])
        return jax.lax.scan(body, ps, None, length=steps)[1]

    states, force = go(physics.to_physics(sys, state))
    return states, np.asarray(force, dtype=np.float64)


def _neutral(vehicle, net_weight: float = 0.0, damping: bool = True):
    """The vehicle's fluid parameters with buoyancy set for `net_weight` (N, weight minus buoyancy)."""
    h = vehicle.sys.hydro
    mass = float(vehicle.mj_model.body_mass[vehicle.sys.body_id])
    h = h.replace(volume=jnp.asarray((mass * G - net_weight) / (float(h.fluid_density) * G), jnp.float32))
    if not damping:
        h = h.replace(linear_damping=jnp.zeros(6), quadratic_damping=jnp.zeros(6))
    return h


def test_scenes_are_listed_and_bad_ones_named():
    assert {"open_water", "seabed", "wall"} <= set(list_scenes())
    with pytest.raises(UserError, match=r"unknown scene 'reef'.*open_water"):
        load_vehicle("bluerov2", scene="reef")
    with pytest.raises(MissingFileError, match="nowhere.xml"):
        load_vehicle("bluerov2", scene="/tmp/nowhere.xml")


def test_a_new_scene_is_one_file(tmp_path):
    """A scene written here, with no code change: a pillar any vehicle can be placed beside."""
    path = tmp_path / "pillar.xml"
    path.write_text('<mujoco><worldbody><geom name="pillar" type="capsule" fromto="3 0 -5 3 0 5" size="0.3" '
                    'priority="1"/></worldbody></mujoco>')
    for name in ("bluerov2", "remus100_four_fin"):
        vehicle = load_vehicle(name, scene=path)
        assert vehicle.sys.contacts and vehicle.scene == str(path)
        assert vehicle.mj_model.geom("scene:pillar").size[0] == pytest.approx(0.3)


def test_a_scene_with_a_moving_body_is_refused(tmp_path):
    path = tmp_path / "buoy.xml"
    path.write_text('<mujoco><worldbody><body name="buoy"><freejoint/><geom size="0.1"/></body></worldbody></mujoco>')
    with pytest.raises(UserError, match="buoy.xml: body 'buoy' has a joint"):
        load_vehicle("bluerov2", scene=path)


def test_the_scene_brings_its_world_and_the_vehicle_keeps_its_names():
    open_water = load_vehicle("remus100")
    wall = load_vehicle("remus100", scene="wall")
    assert not open_water.sys.contacts and wall.sys.contacts
    names = {wall.mj_model.geom(i).name for i in range(wall.mj_model.ngeom)}
    assert {"scene:seabed", "scene:wall", "hull", "collision_hull"} <= names
    assert wall.actuator_names == open_water.actuator_names
    assert wall.mj_model.opt.timestep == open_water.mj_model.opt.timestep
    # visual geoms never collide; collision geoms do, and are hidden in videos (group 3)
    hull = wall.mj_model.geom("hull")
    collision = wall.mj_model.geom("collision_hull")
    assert hull.contype == 0 and hull.conaffinity == 0
    assert collision.contype == 3 and collision.group == 3


def test_the_torpedo_docks_bars_touch_the_hull_and_not_the_fins():
    """Contact bits (marinejax.scene): the dock's bars touch hulls only; the seabed and walls every
    collision geom, fins included."""
    def touch(model, a, b):
        ga, gb = model.geom(a), model.geom(b)
        return bool((ga.contype & gb.conaffinity) | (gb.contype & ga.conaffinity))

    for name in ("remus100", "remus100_four_fin"):
        dock = load_vehicle(name, scene="torpedo_dock").mj_model
        assert touch(dock, "collision_hull", "scene:cone_0") and touch(dock, "collision_hull", "scene:tube_7")
        for fin in ("collision_fins_vertical", "collision_fins_horizontal"):
            assert not touch(dock, fin, "scene:cone_0") and not touch(dock, fin, "scene:tube_7")
        wall = load_vehicle(name, scene="wall").mj_model
        assert touch(wall, "collision_fins_vertical", "scene:wall") and touch(wall, "collision_hull", "scene:seabed")
    rov = load_vehicle("bluerov2_heavy", scene="torpedo_dock").mj_model
    assert touch(rov, "collision_port", "scene:cone_0")


def test_inverse_weights_are_the_rigid_bodys_without_added_mass(tmp_path):
    """The inverse weights marinejax sets (rigid plus added) reduce to MuJoCo's own without added mass."""
    vehicle = load_vehicle("bluerov2_heavy", scene="seabed")
    own = mujoco.MjModel.from_xml_path(str(vehicle.path))
    m, inertia = own.body_mass[1], own.body_inertia[1]
    assert own.body_invweight0[1] == pytest.approx([1 / m, np.mean(1 / inertia)], rel=1e-6)
    added = np.asarray(vehicle.sys.hydro.added_mass)
    assert vehicle.mj_model.body_invweight0[1] == pytest.approx(
        [np.mean(1 / (m + added[:3])), np.mean(1 / (inertia + added[3:]))], rel=1e-6)


@pytest.mark.parametrize("name", ["bluerov2_heavy", "remus100"])
def test_away_from_contacts_a_scene_moves_the_vehicle_as_open_water_does(name):
    """Added mass in MuJoCo's mass matrix (scenes with contacts) against added mass in the applied
    wrench (open water): the same motion on a coupled manoeuvre, 10 s, far above the seabed."""
    open_water, seabed = load_vehicle(name), load_vehicle(name, scene="seabed")
    assert seabed.sys.contacts
    commands = np.clip(np.random.default_rng(0).normal(0.0, 0.5, (100, open_water.num_actuators)), -1, 1)
    start = physics.initial_state(open_water, velocity=(1.0, 0.0, 0.0) if name == "remus100" else (0.2, 0.1, 0.0),
                                  angular_velocity=(0.05, -0.05, 0.1))
    a = physics.rollout(open_water, commands, start, control_dt=0.1, substeps=2)
    b = physics.rollout(seabed, commands, start, control_dt=0.1, substeps=2)
    assert float(jnp.abs(a.position - a.position[0]).max()) > 0.5  # it moved
    np.testing.assert_allclose(b.position, a.position, atol=1e-5)
    np.testing.assert_allclose(b.quaternion, a.quaternion, atol=1e-5)


def test_resting_on_the_seabed_presses_with_the_net_weight():
    vehicle = load_vehicle("bluerov2_heavy", scene="seabed")
    start = physics.initial_state(vehicle, position=(0.0, 0.0, -4.8))  # its collision capsules 0.07 m above the seabed
    states, force = _run(vehicle, start, jnp.zeros(6), 400, 0.05, 4, _neutral(vehicle, net_weight=10.0))
    assert float(states.position[-1, 2]) == pytest.approx(-5.0 + 0.13, abs=0.01)  # on its capsules (radius 0.13 m)
    assert force[-1, 2] == pytest.approx(10.0, rel=1e-3)  # upward, the net weight
    assert np.abs(force[-1, :2]).max() < 1e-2  # no sideways force beyond 0.1 % of it


def test_pushed_against_a_wall_the_contact_force_equals_the_thrust():
    vehicle = load_vehicle("bluerov2_heavy", scene="wall")
    start = physics.initial_state(vehicle, position=(1.5, 0.0, 0.0))
    states, force = _run(vehicle, start, jnp.array([20.0, 0, 0, 0, 0, 0]), 400, 0.05, 4, _neutral(vehicle))
    assert float(states.position[-1, 0]) == pytest.approx(2.0 - 0.26, abs=0.005)  # its capsules' front ends at the wall
    assert abs(float(states.velocity[-1, 0])) < 0.01
    assert force[-1, 0] == pytest.approx(-20.0, rel=5e-3)


def test_an_impact_stops_the_rigid_plus_added_mass_with_the_restitution_of_the_contact_parameters():
    """Drifting into the wall at 0.5 m/s without damping: the contact impulse is (m + X_u̇) Δu, not
    m Δu (the water's inertia takes part in the impact), and the rebound speed is that of MuJoCo's own
    contact on a plain body of that mass in MJX (same geometry, contact parameters and inverse weight,
    1 ms steps)."""
    vehicle = load_vehicle("bluerov2_heavy", scene="wall")
    m = float(vehicle.mj_model.body_mass[1])
    mass = m + float(vehicle.sys.hydro.added_mass[0])
    dt, u0 = 0.002, 0.5
    start = physics.initial_state(vehicle, position=(1.5, 0.0, 0.0), velocity=(u0, 0.0, 0.0))
    states, force = _run(vehicle, start, jnp.zeros(6), 500, dt, 1, _neutral(vehicle, damping=False))
    u1 = float(states.velocity[-1, 0])
    impulse = force[:, 0].sum() * dt
    assert impulse == pytest.approx(mass * (u1 - u0), rel=1e-3)
    assert abs(impulse - m * (u1 - u0)) > 0.3 * abs(impulse)

    xml = f"""<mujoco><option timestep="1e-3" gravity="0 0 0" integrator="Euler" iterations="4" ls_iterations="8">
        <flag eulerdamp="disable"/></option>
      <default><geom solref="0.05 1" friction="0.5 0.005 0.0001" density="0"/></default>
      <worldbody><geom type="plane" pos="2 0 0" zaxis="-1 0 0" size="5 10 0.1"/>
        <body pos="1.5 0 0"><freejoint/><inertial pos="0 0 0" mass="{mass}" diaginertia="1 1 1"/>
          <geom type="capsule" fromto="-0.11 0.135 0 0.13 0.135 0" size="0.13"/>
          <geom type="capsule" fromto="-0.11 -0.135 0 0.13 -0.135 0" size="0.13"/></body></worldbody></mujoco>"""
    reference = mujoco.MjModel.from_xml_string(xml)
    reference.body_invweight0[1] = vehicle.mj_model.body_invweight0[1]
    # MJX's own contact: its capsule-plane contact rebounds differently from MuJoCo's C engine
    # (0.13 against 0.21 for this body; the two agree on boxes)
    model = mjx.put_model(reference)
    data = mjx.make_data(model)
    data = jax.jit(lambda d: jax.lax.fori_loop(0, 1000, lambda i, d: mjx.step(model, d), d))(data.replace(qvel=data.qvel.at[0].set(u0)))
    assert float(data.qvel[0]) < -0.02  # it does bounce
    assert -u1 / u0 == pytest.approx(-float(data.qvel[0]) / u0, abs=0.01)


def test_a_plant_in_a_scene_reports_the_contact_and_an_env_hands_it_to_its_task():
    import marinejax as mj
    from marinejax.plant import Plant, PlantConfig

    plant = Plant("bluerov2_heavy", PlantConfig(scene="wall", action_mode="wrench", control_dt=0.05))
    params = plant.nominal_params()
    params = params.replace(hydro=_neutral(plant.vehicle))
    state = plant.init(jax.random.PRNGKey(0), params, physics.initial_state(plant.vehicle, position=(1.6, 0.0, 0.0)))
    action = jnp.array([20.0, 0, 0, 0, 0, 0]) / jnp.asarray(plant.config.wrench_scale)
    step = jax.jit(lambda s, k: plant.step(params, s, action, k)[0])
    for k in jax.random.split(jax.random.PRNGKey(1), 300):
        state = step(state, k)
    assert float(plant.contact_wrench(state)[0]) == pytest.approx(-20.0, rel=5e-3)
    assert not np.any(np.asarray(Plant("bluerov2_heavy").contact_wrench(state)))  # open water: none

    env = mj.make("BlueROV2Heavy-StationKeeping", scene="wall")
    assert "contact" not in mj.make("BlueROV2Heavy-StationKeeping").reset(jax.random.PRNGKey(0)).info
    s = env.step(env.reset(jax.random.PRNGKey(0)), jnp.zeros(env.action_size))
    assert s.info["contact"].shape == (6,)
    with pytest.raises(UserError, match=r"unknown scene 'reef'"):
        mj.make("BlueROV2Heavy-StationKeeping", scene="reef")


def test_the_rov_dock_guides_a_vehicle_pushed_at_it_off_centre_onto_its_landing_point():
    """A pilot that only pushes towards the station (15 N along world +x) and holds heading 0 docks
    from 0.3 m off the axis: the funnel guides the BlueROV2 Heavy into the cage, onto the back bars."""
    from marinejax.frames import quat_from_euler, quat_to_euler, quat_to_mat

    vehicle = load_vehicle("bluerov2_heavy", scene="rov_dock")
    sys = physics.with_timestep(vehicle.sys.replace(hydro=_neutral(vehicle)), 0.05)

    def pilot(vs):
        force = quat_to_mat(vs.quaternion).T @ jnp.array([15.0, 0.0, 0.0])
        yaw = quat_to_euler(vs.quaternion)[2]
        return jnp.concatenate([force, jnp.array([0.0, 0.0, -20.0 * yaw - 10.0 * vs.angular_velocity[2]])])

    @jax.jit
    def dock(start):
        def body(ps, _):
            ps = physics.control_step(sys, ps, pilot(physics.from_physics(sys, ps)), jnp.zeros(3), 1, mode="wrench")
            return ps, None
        ps = jax.lax.scan(body, physics.to_physics(sys, start), None, length=300)[0]
        return physics.from_physics(sys, ps), ps.data.qfrc_constraint[:3]

    for y0, yaw0 in [(-0.3, -0.1), (0.35, 0.0)]:
        vs, force = dock(physics.initial_state(vehicle, position=(-1.5, y0, 0.05), quaternion=quat_from_euler(0.0, 0.0, yaw0)))
        assert float(vs.position[0]) == pytest.approx(0.0, abs=0.02)  # at the landing point, on the back bars
        assert abs(float(vs.position[1])) < 0.075  # within the cage's 6 cm of play
        assert abs(float(np.degrees(quat_to_euler(vs.quaternion)[2]))) < 5.0
        assert float(force[0]) == pytest.approx(-15.0, rel=1e-2)  # the bars hold the push


def test_the_torpedo_dock_funnels_a_cruising_remus_into_its_tube():
    """The REMUS 100 cruising at 1 m/s with its fins centred, 0.25 m off the dock's axis sideways and
    0.1 m up: the cone turns it into the tube, and it goes on forward through it."""
    vehicle = load_vehicle("remus100", scene="torpedo_dock")
    shaft = 1.0 / 2.554 * 1525.0  # rpm for about 1 m/s
    commands = jnp.tile(jnp.array([0.0, 0.0, shaft / 1525.0 * 2.0 - 1.0]), (80, 1))
    start = physics.initial_state(vehicle, position=(-3.0, 0.25, 0.1), velocity=(1.0, 0.0, 0.0), actuators=(0.0, 0.0, shaft))
    trajectory = physics.rollout(vehicle, commands, start, control_dt=0.1, substeps=2)
    # the nose (body (0.8, 0, 0.02) m from the CG), world frame
    nose = np.asarray(trajectory.position) + np.einsum("tij,j->ti", np.asarray(jax.vmap(quat_to_mat)(trajectory.quaternion)), [0.8, 0.0, 0.02])
    radial = np.hypot(nose[:, 1], nose[:, 2])
    assert radial[0] > 0.25  # it would pass outside the tube's ring of bars (0.20 m)
    in_tube = (nose[:, 0] > 1.0) & (nose[:, 0] < 2.8)  # between the tube's entrance and its end
    assert in_tube.sum() >= 10 and radial[in_tube].max() < 0.2  # it went through inside the ring
    assert nose[-1, 0] > 2.8  # and out of the far end: the bars (frictionless) did not stop it
    assert float(trajectory.velocity[-1, 0]) > 0.5
