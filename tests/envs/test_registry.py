"""The registry: vehicles come from their MJCF files, tasks from one registration each."""

import os
import subprocess
import sys
import uuid

import jax
import numpy as np
import pytest

import marinejax
from marinejax.envs import StationKeeping, env_spec, register_environment, register_task
from marinejax.errors import UserError
from marinejax.vehicle import model_dir

TASKS = ["StationKeeping", "CircleTracking", "HelixTracking", "LemniscateTracking"]


def test_every_vehicle_file_gets_every_task_and_its_disturbed_variant():
    envs = marinejax.list_envs()
    for prefix in ("BlueROV2", "BlueROV2Heavy"):
        for task in TASKS:
            assert f"{prefix}-{task}" in envs and f"{prefix}-{task}Disturbed" in envs
    spec = env_spec("BlueROV2-HelixTrackingDisturbed")
    assert (spec.task, spec.vehicle) == ("HelixTrackingDisturbed", "bluerov2")
    assert spec.config.disturbance.enabled and spec.config.randomization.enabled and spec.config.current.mode == "ou"


def test_tasks_go_to_the_vehicles_of_their_kind():
    """The torpedo REMUS 100 cannot hover: it gets the autopilot, terrain following, path following and
    its own docking and none of the ROV tasks, and asking for one says why; the ROVs get neither the
    autopilot nor path following (terrain following and docking they have, each a class of their own)."""
    torpedo_tasks = ["Docking", "Autopilot", "TerrainFollowing", "WaypointFollowing", "CircleFollowing", "HelixFollowing",
                     "LemniscateFollowing"]
    assert [n for n in marinejax.list_envs() if n.startswith("Remus100-")] == [
        f"Remus100-{t}{variant}" for t in torpedo_tasks for variant in ("", "Disturbed")]
    assert [n for n in marinejax.list_envs() if n.startswith("Remus100FourFin-")] == [
        f"Remus100FourFin-{t}{variant}" for t in torpedo_tasks for variant in ("", "Disturbed")]
    assert not [n for n in marinejax.list_envs() if ("Autopilot" in n or ("Following" in n and "TerrainFollowing" not in n))
                and not n.startswith("Remus100")]
    with pytest.raises(UserError, match="unknown env 'Remus100-StationKeeping'"):
        marinejax.make("Remus100-StationKeeping")
    with pytest.raises(UserError, match="for vehicles of kind \\['rov'\\]; 'remus100' is a 'torpedo'"):
        register_environment("MyRemus-Circle", "CircleTracking", "remus100")


def test_a_new_mjcf_file_is_a_new_vehicle_with_all_tasks():
    """Adding a vehicle is one file: a copy of the BlueROV2 under a new name, nothing else."""
    stem = f"testrov_{uuid.uuid4().hex[:8]}"
    path = model_dir() / f"{stem}.xml"
    # with a sensor of its own: a 5 Hz DVL instead of the default 10 Hz
    text = (model_dir() / "bluerov2.xml").read_text().replace('data="BlueROV2"', 'data="TestRov"').replace(
        "<custom>", '<custom>\n    <numeric name="marinejax:sensors:dvl.rate_hz" data="5"/>')
    code = """
import jax, marinejax
names = [n for n in marinejax.list_envs() if n.startswith("TestRov-")]
env = marinejax.make("TestRov-CircleTracking", episode_length=60)
state = jax.jit(env.step)(jax.jit(env.reset)(jax.random.PRNGKey(0)), jax.numpy.zeros(env.action_size))
same = len(names) == len([n for n in marinejax.list_envs() if n.startswith("BlueROV2-")])
print(len(names) >= 8 and same, env.vehicle.name, env.action_size, bool(jax.numpy.isfinite(state.obs).all()),
      env.config.sensors.dvl.rate_hz, marinejax.make("BlueROV2-CircleTracking").config.sensors.dvl.rate_hz)
"""
    try:
        path.write_text(text)
        proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600, env=os.environ)
    finally:
        path.unlink(missing_ok=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
    # every task (and variant) the BlueROV2 has; its own DVL rate, the default for the others
    assert proc.stdout.split() == ["True", stem, "6", "True", "5.0", "10.0"]


def test_register_environment_adds_a_named_variant():
    config = marinejax.get_default_config("BlueROV2Heavy-StationKeeping")
    name = f"MyStation-{uuid.uuid4().hex[:6]}"
    register_environment(name, "StationKeeping", "bluerov2_heavy", config.__class__(episode_length=100, target_range=0.5))
    assert name in marinejax.list_envs()
    env = marinejax.make(name)
    assert isinstance(env, StationKeeping) and env.config.episode_length == 100 and env.config.target_range == 0.5
    state = jax.jit(env.reset)(jax.random.PRNGKey(0))
    assert np.isfinite(np.asarray(state.obs)).all()
    with pytest.raises(UserError, match="already registered"):
        register_environment(name, "StationKeeping", "bluerov2_heavy")
    with pytest.raises(UserError, match="unknown task 'Hover'; registered tasks"):
        register_environment("X-1", "Hover", "bluerov2_heavy")
    with pytest.raises(UserError, match="unknown vehicle 'submarine'"):
        register_environment("X-2", "StationKeeping", "submarine")
    with pytest.raises(UserError, match="takes a StationKeepingConfig"):
        register_environment("X-3", "StationKeeping", "bluerov2", marinejax.get_default_config("BlueROV2-CircleTracking"))
    with pytest.raises(UserError, match="task 'StationKeeping' is already registered"):
        register_task("StationKeeping", StationKeeping)


# A whole new task: one class and one registration (what `docs/architecture.md` promises).
NEW_TASK = '''
import jax, jax.numpy as jnp
from flax import struct
from marinejax.envs import MarineEnv, register_task
from marinejax.frames import quat_to_mat

@struct.dataclass
class Depth:
    position: jnp.ndarray  # (3,) m, world
    yaw: jnp.ndarray  # () rad

class DepthChange(MarineEnv):
    """Start at the surface-ish depth -1 m and hold a point 2 m deeper."""
    def _sample_task(self, rng):
        return Depth(position=jnp.array([0.0, 0.0, -3.0]), yaw=jax.random.uniform(rng, minval=-3.1, maxval=3.1))
    def target_position(self, info):
        return info["task"].position
    def _initial_pose(self, rng, task):
        return self._random_start(rng, task.position + jnp.array([0.0, 0.0, 2.0]), task.yaw)
    def observe(self, vs, info, action):
        error = quat_to_mat(vs.quaternion).T @ (info["task"].position - vs.position)
        return jnp.concatenate([error, self._attitude_observation(vs, info["task"].yaw), action])
    def reward_terms(self, vs, info, action):
        d = jnp.linalg.norm(info["task"].position - vs.position)
        return {"position": jnp.exp(-d), **self._attitude_terms(vs, info["task"].yaw, action, info["last_action"])}

register_task("DepthChange", DepthChange)
'''


def test_a_new_task_is_one_class_and_one_registration():
    code = NEW_TASK + """
import marinejax
names = sorted(n for n in marinejax.list_envs() if "DepthChange" in n)
env = marinejax.make("BlueROV2-DepthChangeDisturbed")
state = jax.jit(env.reset)(jax.random.PRNGKey(0))
state = jax.jit(env.step)(state, jnp.zeros(env.action_size))
print(" ".join(names), env.observation_size, bool(jnp.isfinite(state.obs).all()))
"""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600, env=os.environ)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split() == ["BlueROV2-DepthChange", "BlueROV2-DepthChangeDisturbed", "BlueROV2Heavy-DepthChange",
                                   "BlueROV2Heavy-DepthChangeDisturbed", "24", "True"]
