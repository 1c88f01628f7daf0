"""A new actuator kind is one class and one registration; vehicle files declare their actuators."""

import math

import jax.numpy as jnp
import numpy as np
import pytest
from flax import struct

import marinejax as mj
from marinejax.actuators import ActuatorKind, list_kinds, register_kind
from marinejax.actuators.base import lag_step, site_frames
from marinejax.errors import UserError
from marinejax.vehicle import model_dir


@struct.dataclass
class FinDesign:
    position: jnp.ndarray  # (3,) m, body frame FLU: centre of pressure
    normal: jnp.ndarray  # (3,) the fin's lift direction at zero deflection (site +z)
    area_lift: jnp.ndarray  # () ½ ρ A C_Lδ, N s²/m² per rad


@struct.dataclass
class FinParams:
    max_angle: jnp.ndarray  # () rad
    time_constant: jnp.ndarray  # () s


class TestFin(ActuatorKind):
    """A control fin as the torpedo issue needs one: the command sets a lagged deflection δ, and the
    lift ½ρAC_Lδ u_r|u_r| grows with the square of the local relative surge velocity."""

    name = "test_fin"

    def load(self, m, sites, settings, where):
        self.check_settings(settings, ("area_lift", "max_angle", "time_constant"), where)
        positions, rotations = site_frames(m, sites)
        design = FinDesign(position=jnp.asarray(np.float32(positions[0])), normal=jnp.asarray(np.float32(rotations[0][:, 2])),
                           area_lift=jnp.float32(settings["area_lift"][0]))
        return design, FinParams(max_angle=jnp.float32(settings["max_angle"][0]), time_constant=jnp.float32(settings["time_constant"][0]))

    def target(self, design, params, command):
        return jnp.clip(command, -1.0, 1.0) * params.max_angle

    def advance(self, design, params, state, target, dt):
        return lag_step(state, target, dt, params.time_constant)

    def wrench(self, design, params, state, nu_r):
        local = nu_r[:3] + jnp.cross(nu_r[3:], design.position)  # water velocity at the fin, body frame
        force = design.area_lift * state[0] * local[0] * jnp.abs(local[0]) * design.normal
        return jnp.concatenate([force, jnp.cross(design.position, force)])

    def describe(self, names, params):
        return f"fin deflection in [-1, 1] of max_angle, order {list(names)}"


FIN = TestFin()
AREA_LIFT = 4.0  # N s²/m² per rad


@pytest.fixture(scope="module")
def finned(tmp_path_factory):
    """The BlueROV2 Heavy with one fin added at its stern: one site and three settings in its file."""
    if FIN.name not in list_kinds():
        register_kind(FIN)
    text = (model_dir() / "bluerov2_heavy.xml").read_text()
    text = text.replace('<site name="thruster1"', '<site name="fin1" pos="-0.3 0 0" zaxis="0 1 0" size="0.01"/>\n      <site name="thruster1"', 1)
    text = text.replace('data="thruster:t200"', 'data="thruster:t200 fin:test_fin"').replace(
        "</custom>", f'<numeric name="marinejax:fin:area_lift" data="{AREA_LIFT}"/><numeric name="marinejax:fin:max_angle" data="0.3"/>'
                     '<numeric name="marinejax:fin:time_constant" data="0.1"/></custom>')
    path = tmp_path_factory.mktemp("vehicles") / "finned_heavy.xml"
    path.write_text(text)
    return mj.load_vehicle(str(path))


def test_a_vehicle_declares_groups_in_action_order(finned):
    assert finned.num_actuators == 9 and finned.actuator_names[-1] == "fin1"
    assert [g.kind.name for g in finned.sys.actuators] == ["t200", "test_fin"]
    assert "T200 throttle" in finned.describe_action() and finned.describe_action().endswith("order ['fin1']")


def test_the_fin_lags_and_its_force_needs_flow(finned):
    """δ follows its 0.1 s lag; at rest a deflected fin makes no force; with the water passing at
    1 m/s from the bow (a current of 1 m/s along the body's −x) its lift is AREA_LIFT · δ N along its
    normal (+y, port) at x = −0.3 m, so the vehicle starts to drift to port and its bow to yaw to
    starboard."""
    command = np.zeros((20, 9), np.float32)
    command[:, 8] = 1.0
    still = mj.rollout(finned, command, mode="thrusters")
    np.testing.assert_allclose(np.asarray(still.actuators[0, 8]), 0.3 * (1 - math.exp(-0.05 / 0.1)), rtol=1e-5)
    np.testing.assert_allclose(np.asarray(still.velocity[:, 1]), 0.0, atol=1e-6)
    fin = finned.sys.actuators[1]
    wrench = fin.kind.wrench(fin.design, fin.params, jnp.array([0.3]), jnp.array([1.0, 0, 0, 0, 0, 0]))
    np.testing.assert_allclose(np.asarray(wrench), [0, AREA_LIFT * 0.3, 0, 0, 0, -0.3 * AREA_LIFT * 0.3], atol=1e-6)
    flow = mj.rollout(finned, command[:4], mode="thrusters", current=[-1.0, 0.0, 0.0])  # the first 0.2 s
    assert float(flow.velocity[-1, 1]) > 5e-4 and float(flow.angular_velocity[-1, 2]) < -5e-3


def test_bad_declarations_are_user_errors(tmp_path):
    base = (model_dir() / "bluerov2.xml").read_text()
    cases = {
        "unknown kind": (base.replace('data="thruster:t200"', 'data="thruster:warp_drive"'), "warp_drive"),
        "no declaration": (base.replace('<text name="marinejax:actuators" data="thruster:t200"/>', ""), "no actuators declared"),
        "missing sites": (base.replace('data="thruster:t200"', 'data="thruster:t200 fin:t200"'), "fin1..finN"),
        "unknown setting": (base.replace("</custom>", '<numeric name="marinejax:thruster:voltag" data="16"/></custom>'), "voltag"),
        "bad setting": (base.replace('"marinejax:thruster:voltage" data="16"', '"marinejax:thruster:voltage" data="42"'), "voltage"),
    }
    for what, (text, match) in cases.items():
        path = tmp_path / f"{what.replace(' ', '_')}.xml"
        path.write_text(text)
        with pytest.raises(UserError, match=match):
            mj.load_vehicle(str(path))
