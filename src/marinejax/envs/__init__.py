"""Registered RL tasks: station keeping, docking, obstacle avoidance and circle, helix and lemniscate tracking for ROVs; the
autopilot, terrain following, waypoint, circle, helix and lemniscate path following and docking for torpedo AUVs.

    env = marinejax.make("BlueROV2Heavy-StationKeeping", current={"mode": "constant"})
    state = jax.jit(env.reset)(jax.random.PRNGKey(0))

A new task is one module (a `MarineEnv` subclass) plus one `register_task` line below; a new vehicle
is one MJCF file in models/mjcf/ (see `registry`).
"""

from marinejax.envs.base import EnvConfig, MarineEnv, ResetConfig, RewardConfig
from marinejax.plant import CurrentConfig, DisturbanceConfig, RandomizationConfig
from marinejax.envs.registry import (
    env_spec,
    get_default_config,
    list_envs,
    make,
    register_environment,
    register_task,
    register_with_brax,
)
from marinejax.envs.autopilot import Autopilot, AutopilotConfig
from marinejax.envs.docking import Docking, DockingConfig
from marinejax.envs.obstacle_avoidance import ObstacleAvoidance, ObstacleAvoidanceConfig
from marinejax.envs.path_following import PathFollowing, PathFollowingConfig
from marinejax.envs.rov_terrain_following import RovTerrainFollowing, RovTerrainFollowingConfig
from marinejax.envs.station_keeping import StationKeeping
from marinejax.envs.terrain_following import TerrainFollowing, TerrainFollowingConfig
from marinejax.envs.torpedo_docking import TorpedoDocking, TorpedoDockingConfig
from marinejax.envs.tracking import TrackingConfig, Tracking
from marinejax.envs.trajectories import TrajectoryConfig
from marinejax.envs.wrappers import FixedEpisodes, wrap_for_training

register_task("StationKeeping", StationKeeping)
register_task("Docking", Docking)  # ROVs, in the rov_dock scene
register_task("Docking", TorpedoDocking)  # torpedo AUVs, in the torpedo_dock scene
register_task("ObstacleAvoidance", ObstacleAvoidance)  # ROVs, in the pillars scene, with the sonar
register_task("Autopilot", Autopilot)  # torpedo AUVs
register_task("TerrainFollowing", TerrainFollowing)  # torpedo AUVs, in the terrain scene, with the altimeter and sonar
register_task("TerrainFollowing", RovTerrainFollowing)  # ROVs, along a transect over the terrain scene
register_task("WaypointFollowing", PathFollowing, kind="lines")
register_task("CircleFollowing", PathFollowing, kind="circle")
register_task("HelixFollowing", PathFollowing, kind="helix")
register_task("LemniscateFollowing", PathFollowing, kind="lemniscate")
register_task("CircleTracking", Tracking, kind="circle")
register_task("HelixTracking", Tracking, kind="helix")
register_task("LemniscateTracking", Tracking, kind="lemniscate")
# Fast variants at 0.6-0.8 m/s, near the vehicles' top speed: the Munk moment pitches the vehicle and
# thrusters saturate, where controllers differ (the 0.2-0.5 m/s defaults are easy for all of them).
_FAST = TrackingConfig(trajectory=TrajectoryConfig(speed=(0.6, 0.8)))
register_task("CircleTrackingFast", Tracking, config=_FAST, kind="circle")
register_task("HelixTrackingFast", Tracking, config=_FAST, kind="helix")
register_task("LemniscateTrackingFast", Tracking, config=_FAST, kind="lemniscate")

__all__ = [
    "Autopilot",
    "AutopilotConfig",
    "CurrentConfig",
    "Docking",
    "DockingConfig",
    "DisturbanceConfig",
    "EnvConfig",
    "FixedEpisodes",
    "MarineEnv",
    "ObstacleAvoidance",
    "ObstacleAvoidanceConfig",
    "PathFollowing",
    "PathFollowingConfig",
    "RandomizationConfig",
    "ResetConfig",
    "RewardConfig",
    "RovTerrainFollowing",
    "RovTerrainFollowingConfig",
    "TerrainFollowing",
    "TerrainFollowingConfig",
    "TorpedoDocking",
    "TorpedoDockingConfig",
    "env_spec",
    "get_default_config",
    "list_envs",
    "make",
    "register_environment",
    "register_task",
    "register_with_brax",
    "wrap_for_training",
]
