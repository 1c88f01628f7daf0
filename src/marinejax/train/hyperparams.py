"""Training settings, kept apart from the env configs: the algorithm (PPO or SAC, `ppo`/`sac`) and
its settings, tuned values per task; the env, network and saved config a training config stands for.

`tuned_config(env_name)` gives the settings the results in docs/results.md come from; any field can be
overridden (`with_overrides`), and a misspelled key is an error.
"""

from __future__ import annotations

import dataclasses
import json
import types
from pathlib import Path
from typing import Any, Callable, Mapping

from marinejax.config import apply_overrides
from marinejax.envs.base import MarineEnv
from marinejax.envs.registry import env_spec, make
from marinejax.envs.symmetry import env_mirror
from marinejax.errors import UserError
from marinejax.train import ppo, sac


PPOConfig = ppo.Config
SACConfig = sac.Config
ALGORITHMS = types.MappingProxyType({"ppo": ppo, "sac": sac})  # name → module (`ppo` documents what each provides)


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    """What `marinejax train` runs: an env with config overrides, and the settings of the algorithm
    (`algorithm`: a key of ALGORITHMS; its settings are the field of that name)."""

    env: str
    ppo: PPOConfig = PPOConfig()
    env_overrides: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    algorithm: str = "ppo"
    sac: SACConfig = SACConfig()

    def __post_init__(self):
        if self.algorithm not in ALGORITHMS:
            raise UserError(f"unknown algorithm {self.algorithm!r}; valid: {list(ALGORITHMS)}")

    @property
    def agent(self) -> PPOConfig | SACConfig:
        """The settings of the algorithm that trains (num_timesteps, num_envs, seed, ...)."""
        return getattr(self, self.algorithm)

    @property
    def module(self):
        """The algorithm's module (`ppo` or `sac`)."""
        return ALGORITHMS[self.algorithm]


# Tuned on BlueROV2Heavy-StationKeeping on the 2-core CPU and judged over seeds 0-4 (docs/results.md).
# With the second-order physics the env costs little, so 12 M env steps fit in about 3.5 minutes
# (about 80 k env steps/s after compilation). With 4 M steps some seeds stay in a 0.25 m orbit
# around the target; every seed tried broke out between 2.5 M and 7 M steps. Tracking learns in
# about 1.5 M steps and keeps 4 M.
_STATION = PPOConfig(
    num_timesteps=12_000_000, num_minibatches=4, unroll_length=10, learning_rate=1e-3, entropy_cost=1e-4,
    discounting=0.98, num_evals=20,
)
# SAC, the same for every task: 0.5 M env steps (about 4 minutes on the 2-core CPU). On station
# keeping seed 0 reached 5 mm after 0.23 M steps (docs/results.md: seeds 0-4).
_SAC = SACConfig(num_timesteps=500_000)
_TRACKING = dataclasses.replace(_STATION, num_timesteps=4_000_000, num_evals=10)
# Pose keeping: the rate held for the first half, then falling linearly to 0 at 12 M steps. With the
# constant rate the policy kept moving at the millimetre scale to the end, and the latest checkpoint
# was 1.3-3.7× the best on three seeds of five of each vehicle; with the schedule on one or two,
# and nine seeds of ten end more accurate (median 2.8 against 4.3 mm on the Heavy, 1.4 against
# 3.9 mm on the BlueROV2; docs/results.md).
_DECAYING_RATE = {"learning_rate_schedule": "linear", "decay_start": 0.5, "final_learning_rate": 0.0}
_POSE = dataclasses.replace(_STATION, **_DECAYING_RATE)
_TUNED: dict[str, tuple[PPOConfig, dict[str, Any]]] = {
    "StationKeeping": (_POSE, {}),
    "CircleTracking": (_TRACKING, {}),
    "HelixTracking": (_TRACKING, {}),
    "LemniscateTracking": (_TRACKING, {}),
}
# Torpedo path following (10 Hz, 60 s episodes): the station-keeping recipe for 8 M steps. On the
# circle, seed 0 was at 0.04 m after 3.2 M steps and at best 0.034 m (with the cross-track integral
# observed; without it, 0.50 m at 6.3 M steps). docs/results.md: seeds 0-4.
_PATH = dataclasses.replace(_STATION, num_timesteps=8_000_000, num_evals=16)
_TUNED["WaypointFollowing"] = (_PATH, {})
# The circle: a mirror-symmetric policy on two CPU devices. The plain policy sometimes learned to turn
# one way only (a seed's clockwise circles 0.48 m, its counter-clockwise ones 0.03 m); symmetric,
# every seed 0-4 within 0.044 m in 126-192 s of training (one device, plain: 235-346 s), one seed
# flying 1 m/s over the commanded speed (docs/results.md).
_CIRCLE = dataclasses.replace(_PATH, cpu_devices=2, mirror_symmetric=True)
_TUNED["CircleFollowing"] = (_CIRCLE, {})
# Helix and lemniscate: with the 2 s leak of the observed error integral a slow helix seed flew a
# steady 0.3-1 m outside and below the path for millions of steps (the integral saturates); a 10 s
# leak lets the policy integrate that offset away; with 512 envs and a 512 batch. Seeds 0-4: 4 of 5 within
# 0.10 m on each path (the path recipe: 3 of 5), every seed holding the commanded speed (within
# 45 mm/s; the path recipe left one lemniscate seed 0.96 m/s off) (docs/results.md).
_CURVED = (dataclasses.replace(_PATH, num_envs=512, batch_size=512), {"integral_time_constant": 10.0})
_TUNED.update({"HelixFollowing": _CURVED, "LemniscateFollowing": _CURVED})
# The torpedo autopilot (120 s episodes of two set-points): a 10 s horizon (γ 0.99 at 10 Hz) and
# Brax's usual entropy bonus, 1e-2. Brax's entropy estimate includes the tanh's log-Jacobian at the
# drawn action, so the bonus pulls the policy off fin angles held at their limits; with our 1e-4 the
# fins stayed there for 15-20 M steps. On one device 20 M steps brought seeds 0-4 within 0.016-0.064
# m, 1.2° and 0.024 m/s in 461-532 s. Two CPU devices and the decaying rate, with the best checkpoint
# chosen on all three of the task's targets (`best_on="targets"`; on the depth alone it can trade the
# speed and heading for it, 3.4° and 0.22 m/s off) over fixed training-evaluation episodes: 18 M
# steps bring seeds 0-4 within 6-36 mm of depth, at least the classical autopilot's 37 mm, 0.8° and
# 7 mm/s in 262-326 s (held-out seeds 5 and 6: 33 mm and 0.131 m, still marginal). 12 M steps took
# 175-214 s but left seed 2 at 0.090 m and seed 5 at 0.104 m, their large dives closing slowly
# (`reward.dive` settled those but cost another seed its speed or heading), docs/results.md.
_AUTOPILOT_1E4 = dataclasses.replace(_STATION, num_timesteps=20_000_000, discounting=0.99)
_TUNED["Autopilot"] = (dataclasses.replace(_AUTOPILOT_1E4, entropy_cost=1e-2, num_timesteps=18_000_000, cpu_devices=2,
                                           fixed_eval_episodes=True, best_on="targets", **_DECAYING_RATE), {})
# Terrain following: the autopilot's recipe with the entropy 1e-4 of its measurements, from scratch:
# seeds 0, 1 and 3 at 0.17-0.29 m, measured before the task observed the seabed ahead (the classical
# autopilot 0.167 m; anticipating the seabed ahead, 0.088 m). Its observation extends the autopilot's,
# but the shipped autopilot policy (0.29 m before training) fine-tuned for 2-4 M steps did not improve
# on seed 0 (learning rates 1e-3, 3e-4, 1e-4: 0.28 m at best, later 0.30-0.41 m). With the seabed ahead
# observed, the nominal autopilot's recipe at 12 M steps learnt the altitude (0.14 m) only while flying
# 0.4 m/s too fast, and lost it as it learnt the speed (docs/results.md).
_TUNED["TerrainFollowing"] = (_AUTOPILOT_1E4, {})
# Obstacle avoidance (10 Hz, 60 s episodes, the sonar in the observation): a 10 s horizon as the
# autopilot's; seeds 0-4 succeed in 91-95 % of the evaluation episodes after 10 M steps (docs/tasks.md).
_TUNED["ObstacleAvoidance"] = (dataclasses.replace(_STATION, num_timesteps=10_000_000, discounting=0.99, num_evals=10), {})
_TUNED.update({f"{task}Fast": _TUNED[task] for task in ("CircleTracking", "HelixTracking", "LemniscateTracking")})
_TUNED.update({f"{task}Disturbed": settings for task, settings in list(_TUNED.items())})
# Under disturbance the latest checkpoint was already within 1.3× of the best on every seed with the
# constant rate, the recipe its results were measured with (docs/results.md).
_TUNED["StationKeepingDisturbed"] = (_STATION, {})
# Nominal tracking (not its Fast and Disturbed variants, which keep _TRACKING): two CPU devices for
# 3 M env steps, the rate held for the first half then falling linearly to 0. Seeds 0-4 of both
# vehicles' three trajectories within 12 mm (Heavy 0.9-1.8 mm, BlueROV2 4.2-12.1 mm) in 36-41 s of
# training with the compilation cache warm and 74-78 s from cold, against 64 and 117 s for 4 M steps
# on one device (Heavy 0.9-1.2 mm, BlueROV2 3.1-7.0 mm). With 2 M steps four of the 19 seeds run ended
# at 2.0-2.3 cm (docs/results.md).
_TRACKING_2DEV = dataclasses.replace(_TRACKING, num_timesteps=3_000_000, cpu_devices=2, **_DECAYING_RATE)
_TUNED.update({task: (_TRACKING_2DEV, {}) for task in ("CircleTracking", "HelixTracking", "LemniscateTracking")})
# Per env, where a vehicle needs its own recipe. The 6-thruster BlueROV2 learns station keeping's
# position more slowly than the Heavy; with the sharp heading term at the task's weight 1 two seeds of
# five ended at 17 and 26 mm, with half of it every seed within 1 cm and 0.2° (docs/results.md).
_BLUEROV2_POSE = {"reward.heading_precision": 0.5}
# Under the disturbance torque it pitches (median 29°: it cannot make a pitch moment), and with the
# shared recipe its error was a 1.4 Hz sway/roll oscillation with a 95th percentile over 60 mm on
# some seeds. Ten times the smoothness and angular-velocity weights damp it, and 128-128 networks
# fit the wider range of attitudes (docs/results.md: seeds 0-4).
_TUNED_ENVS: dict[str, tuple[PPOConfig, dict[str, Any]]] = {
    "BlueROV2-StationKeeping": (_POSE, _BLUEROV2_POSE),
    "BlueROV2-StationKeepingDisturbed": (
        dataclasses.replace(_STATION, policy_hidden=(128, 128), value_hidden=(128, 128)),
        {**_BLUEROV2_POSE, "reward.smoothness": 0.1, "reward.angular_velocity": 0.1},
    ),
}
# The REMUS 100's helix, lemniscate and waypoints (not the four-fin variant's: another action size).
# From scratch the curved paths left a seed in five at 0.19-0.39 m, and no change of exploration,
# normalizer, reward or integral landed them all; waypoints landed every seed from scratch (the path
# recipe) but in 342-361 s. A curriculum lands all three in 85-142 s: the shipped circle policy
# (`policies/Remus100-CircleFollowing`, the circle's recipe, seed 0) fine-tuned on the path with the
# circle's settings for 4 M steps (docs/results.md: seeds 0-4). The disturbed paths (currents, new
# physics, paths fitted to what the vehicle can turn and climb) start from it too: every seed 0-4 of
# every path within 0.062-0.092 m in 80-140 s; from scratch with their task's recipe no seed came
# within 0.45 m (docs/results.md).
_FROM_CIRCLE = (dataclasses.replace(_CIRCLE, num_timesteps=4_000_000, init_from="Remus100-CircleFollowing"), {})
_TUNED_ENVS.update({f"Remus100-{task}{d}": _FROM_CIRCLE for task in ("HelixFollowing", "LemniscateFollowing", "WaypointFollowing")
                    for d in ("", "Disturbed")})
_TUNED_ENVS["Remus100-CircleFollowingDisturbed"] = _FROM_CIRCLE
# The disturbed autopilot fine-tunes the shipped autopilot policy with the autopilot's settings for
# 6 M steps (0.68-1.03 m of depth error before its set-points were fitted to the current and its
# currents made horizontal). With the task's heading and speed terms one seed of five ended 2.5° off
# its heading; sharper ones (0.2 rad, 0.25 m/s) bring every seed's latest checkpoint within all three
# targets, and training evaluations on fixed episodes make the best checkpoint one that is too: seeds
# 0-4 within 0.087 m, 1.7° and 0.047 m/s in 137-200 s (docs/results.md).
_TUNED_ENVS["Remus100-AutopilotDisturbed"] = (
    dataclasses.replace(_AUTOPILOT_1E4, num_timesteps=6_000_000, init_from="Remus100-Autopilot", fixed_eval_episodes=True),
    {"reward.heading_precision_scale": 0.2, "reward.speed_scale": 0.25},
)
# Torpedo docking (the same task name as the ROVs' docking, another class): a straight path ending in
# the funnel. From scratch with the path recipe four seeds of five docked in 77-94 % of the episodes
# and one never, in 376-598 s. Its observation is path following's plus the latch point (`dock`): the
# shipped circle policy, the new field entering with weights 0 (`ppo.widen_inputs`), docks every
# nominal evaluation episode before any training and 26 of 64 disturbed ones; fine-tuned with the
# circle's settings: every nominal episode docked on seeds 0-4 in 62-112 s, 81-92 % of the disturbed
# ones in 178-210 s (docs/results.md). The four-fin variant keeps the path recipe.
_DOCK = dataclasses.replace(_CIRCLE, init_from="Remus100-CircleFollowing", normalizer_warmup=50)
_TUNED_ENVS["Remus100-Docking"] = (dataclasses.replace(_DOCK, num_timesteps=2_000_000), {})
_TUNED_ENVS["Remus100-DockingDisturbed"] = (dataclasses.replace(_DOCK, num_timesteps=6_000_000), {})
# The four-fin variant (another action size): each task starts from the REMUS 100 policy the REMUS's
# recipe starts from, or for the REMUS's from-scratch autopilot and circle from the REMUS's shipped
# policy of the task, each fin following the command of its pair (`ppo.action_map`), and fine-tunes
# with the REMUS's settings. Before any training the REMUS autopilot flies the four-fin autopilot
# within 0.011 m of depth, 0.9° and 0.016 m/s, its circle policy the circle within 0.038 m; fine-tuned,
# seeds 0-4 of the nominal tasks land in 55-188 s, the disturbed paths within 0.053-0.085 m and the
# disturbed docking 78-94 % docked; the disturbed autopilot (the REMUS's recipe, from the REMUS
# autopilot policy) within 0.065 m, 1.6° and 0.043 m/s in 158-249 s (docs/results.md).
_FOUR_FIN = {"Autopilot": (dataclasses.replace(_AUTOPILOT_1E4, num_timesteps=2_000_000, num_evals=10, init_from="Remus100-Autopilot"), {}),
             "CircleFollowing": (dataclasses.replace(_CIRCLE, num_timesteps=2_000_000, init_from="Remus100-CircleFollowing"), {})}
_FOUR_FIN.update({task: _TUNED_ENVS[f"Remus100-{task}"] for task in ("AutopilotDisturbed", "CircleFollowingDisturbed")})
_FOUR_FIN.update({f"{task}{d}": _TUNED_ENVS[f"Remus100-{task}{d}"] for task in ("HelixFollowing", "LemniscateFollowing", "WaypointFollowing", "Docking")
                  for d in ("", "Disturbed")})
_TUNED_ENVS.update({f"Remus100FourFin-{task}": settings for task, settings in _FOUR_FIN.items()})
# ROV docking: station keeping towards the task's guide point on the station's axis plus the landing
# point (`dock`), so the shipped station-keeping policy of the same vehicle and variant starts it (the
# new field entering with weights 0) and docks every nominal evaluation episode before any training.
# Fine-tuned with its recipe for 2 M steps: every seed 0-4 docks in 98-100 % of the episodes, Heavy
# nominal and disturbed and BlueROV2 nominal; the BlueROV2 also with the smoothness and
# angular-velocity weights of its disturbed station keeping, against rocking in place (the disturbed
# BlueROV2: 8-59 % on the tries, rocking at the landing point faster than the docked 0.1 m/s,
# pitched by the disturbance; docs/results.md).
_BLUEROV2_DOCK = {"reward.smoothness": 0.1, "reward.angular_velocity": 0.1}


def _docking_from_station_keeping(vehicle: str, disturbed: str) -> tuple[PPOConfig, dict[str, Any]]:
    source = f"{vehicle}-StationKeeping{disturbed}"
    ppo_config, env_overrides = _TUNED_ENVS.get(source) or _TUNED[f"StationKeeping{disturbed}"]
    env_overrides = {**env_overrides, **(_BLUEROV2_DOCK if vehicle == "BlueROV2" else {})}
    return dataclasses.replace(ppo_config, num_timesteps=2_000_000, num_evals=10, init_from=source, normalizer_warmup=50), env_overrides


_TUNED_ENVS.update({f"{vehicle}-Docking{d}": _docking_from_station_keeping(vehicle, d) for vehicle in ("BlueROV2Heavy", "BlueROV2")
                    for d in ("", "Disturbed")})

# ROV terrain following (the same task name as the torpedo's, another class; 10 Hz, 60 s episodes):
# nominal tracking's recipe (a reference moving along the transect as tracking's does along its
# trajectory: two CPU devices for 4 M env steps, the decaying rate) with station keeping's sharp
# heading term. With the tracking recipe and the task's broad heading term alone the Heavy's seeds 0-4
# held the transect's heading only to 15-22°; with these, within 0.29-0.64° at about the same altitude
# error (0.031-0.044 m, was 0.030-0.055 m) in 123-186 s of training instead of 239-302 s
# (docs/results.md). On seeds 0-4 the BlueROV2 holds 0.048-0.065 m and the disturbed Heavy 0.031-0.042 m;
# the disturbed BlueROV2 0.090-0.303 m, one seed over the 0.2 m target (docs/results.md).
_ROV_TERRAIN = (dataclasses.replace(_TRACKING, cpu_devices=2, **_DECAYING_RATE),
                {"reward.heading_precision": 1.0, "reward.heading_precision_scale": 0.1})
_TUNED_ENVS.update({f"{vehicle}-TerrainFollowing{d}": _ROV_TERRAIN for vehicle in ("BlueROV2Heavy", "BlueROV2")
                    for d in ("", "Disturbed")})


def tuned_config(env_name: str, algorithm: str = "ppo") -> TrainConfig:
    """The tuned training settings of env `env_name` (raises listing the registered envs if unknown)
    for `algorithm`: with PPO its own recipe if it has one, else its task's; a task without tuned
    settings gets the station-keeping recipe, the most demanding one. SAC: `_SAC`."""
    task = env_spec(env_name).task
    if algorithm not in ALGORITHMS:
        raise UserError(f"unknown algorithm {algorithm!r}; valid: {list(ALGORITHMS)}")
    if algorithm == "sac":
        return TrainConfig(env=env_name, algorithm="sac", sac=_SAC)
    ppo_config, env_overrides = _TUNED_ENVS.get(env_name) or _TUNED.get(task, (_STATION, {}))
    return TrainConfig(env=env_name, ppo=ppo_config, env_overrides=dict(env_overrides))


def with_overrides(config: TrainConfig, ppo: Mapping[str, Any] | None = None, env: Mapping[str, Any] | None = None,
                   agent: Mapping[str, Any] | None = None) -> TrainConfig:
    """Validated copy: `agent` keys are fields of the training algorithm's settings (`ppo` keys of
    PPOConfig's, for a PPO config only); `env` keys are env config keys (dotted or nested)."""
    if ppo and config.algorithm != "ppo":
        raise UserError(f"PPO settings ({sorted(ppo)}) given for a {config.algorithm} run; use the algorithm's options")
    overrides = {**(ppo or {}), **(agent or {})}
    new_agent = apply_overrides(config.agent, overrides, prefix=f"{config.algorithm}.")
    merged = {**config.env_overrides, **(env or {})}
    return dataclasses.replace(config, **{config.algorithm: new_agent}, env_overrides=merged)


def network_factory(ppo_config: PPOConfig, observation_size: int | Mapping | None = None, env: MarineEnv | None = None) -> Callable:
    """Brax's PPO networks with our sizes (`ppo.network_factory`); a mirror-symmetric policy needs
    the env it is trained on (`ppo.env_network_factory`)."""
    if env is not None:
        return ppo.env_network_factory(ppo_config, env)
    if ppo_config.mirror_symmetric:
        raise UserError("a mirror-symmetric policy (ppo mirror_symmetric) needs its env: network_factory(settings, env=env)")
    return ppo.network_factory(ppo_config, observation_size)


def build_env(config: TrainConfig) -> MarineEnv:
    """The env of a training config: its registered env with the config's overrides (a
    mirror-symmetric PPO policy's env must have a mirror image: `envs.symmetry.env_mirror`)."""
    env = make(config.env, **config.env_overrides)
    if config.algorithm == "ppo" and config.ppo.mirror_symmetric:
        env_mirror(env)  # raises naming the fields without one
    return env


def load_train_config(run_dir: Path) -> TrainConfig:
    """The training config a run directory's config.json records."""
    data = json.loads((Path(run_dir) / "config.json").read_text())
    algorithm = data.get("algorithm", "ppo")  # runs written before SAC have no "algorithm"
    if algorithm not in ALGORITHMS:
        raise UserError(f"{run_dir}: unknown algorithm {algorithm!r} in config.json; valid: {list(ALGORITHMS)}")
    settings = ALGORITHMS[algorithm].Config.from_dict(data[algorithm])
    return TrainConfig(env=data["env"], env_overrides=data["env_overrides"], algorithm=algorithm, **{algorithm: settings})
