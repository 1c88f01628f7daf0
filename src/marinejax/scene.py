"""Scenes: the world a vehicle is placed in, one MJCF file each in `models/scenes/` (installed as
`marinejax/models/scenes/`). Adding a scene means adding one file; no code change.

A scene file holds everything that is not the vehicle: seabed, walls, obstacles, docking
stations, lights and the sky, as geoms of its worldbody or of bodies without joints (static). Its
`<option><flag contact=... constraint=.../>` says whether contacts are on; its geoms' `solref`,
`solimp` and `friction` are the contact parameters, its solver options (`solver`, `iterations`,
`ls_iterations`, `tolerance`, `cone`, ...) MuJoCo's contact solver. The other options (time step,
gravity, the zero fluid density of MuJoCo's own fluid model) are the vehicle's. `compose` places a vehicle's
MJCF in a scene: the vehicle keeps its names, options and custom data; the scene's names get the
prefix "scene:" (the geom "wall" becomes "scene:wall").

Give the scene's geoms `priority="1"` so that their contact parameters win over the vehicle's
(MuJoCo otherwise takes the larger friction of the two geoms, and a vehicle's geoms have MuJoCo's
default of 1).

Which geoms touch (MuJoCo's contype/conaffinity bits): a vehicle's collision geoms have bit 1, and
its hull's (the body, not appendages such as fins) also bit 2; a scene geom with MuJoCo's default
(contype = conaffinity = 1) touches every collision geom, one with contype = conaffinity = 2 only
hulls. MJX collides every pair that may touch at every step, so a geom that only a hull can reach
first should say so (the torpedo dock's bars: the fins, 1.5 m behind the nose, reach them only
once the nose is past the tube's entrance, where the latch holds the vehicle).

A dock that holds a vehicle: a scene site named `latch` is the seat where a docked vehicle's site
`nose` is held. `compose` joins the two by a weld equality constraint named `latch`, open (inactive)
at the start of every episode; the task that docks closes it (`Plant.latch`), and MuJoCo's
constraint solver then draws the vehicle's nose site onto the seat, its frame onto the seat's, with
the time constant `LATCH_SOLREF` gives (critically damped), and holds it there against its
thrust. A vehicle without a `nose` site gets no latch.

Scenes shipped: open_water (the default; no contacts, a seabed drawn 10 m below for videos),
seabed (a hard flat seabed at world z = −5 m), wall (that seabed and a wall, the plane x = 2 m),
rov_dock (an ROV docking cage with a funnel, landing point at the origin), torpedo_dock (a cone
narrowing to a tube along +x, for the REMUS 100, with a latch), pillars (twelve piles a task places per episode)
and terrain (a seabed of blocks along +x whose heights a task draws per episode).
"""

from __future__ import annotations

from pathlib import Path

import mujoco

from marinejax.errors import MissingFileError, UserError
from marinejax.model_files import models_dir

DEFAULT_SCENE = "open_water"
PREFIX = "scene:"  # of every name the scene brings (geoms, bodies, materials, lights)
_WORLD_FLAGS = mujoco.mjtDisableBit.mjDSBL_CONTACT | mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
# Options are the vehicle's (its physics) or the scene's (the contact solver); each side's are copied
# onto the other before attaching, so that MuJoCo sees no conflict.
_VEHICLE_OPTIONS = ("timestep", "gravity", "density", "viscosity", "wind", "magnetic", "integrator", "jacobian", "enableflags")
_SCENE_OPTIONS = ("solver", "iterations", "ls_iterations", "tolerance", "ls_tolerance", "cone", "impratio", "noslip_iterations")
LATCH = "latch"  # the scene's seat site, and the weld's name
NOSE = "nose"  # the vehicle's site a latch holds
# s, damping ratio: a vehicle latched at 2 m/s stops within about 0.15 m (v · τ / e); MuJoCo keeps
# the time constant at least two physics steps (0.1 s at the torpedo's 50 ms)
LATCH_SOLREF = (0.2, 1.0)


def scene_dir() -> Path:
    """Folder holding the scene MJCF files."""
    return models_dir("scenes")


def list_scenes() -> list[str]:
    """Names of the available scenes (MJCF file stems), computed when asked."""
    return sorted(p.stem for p in scene_dir().glob("*.xml"))


def scene_path(scene: str | Path) -> Path:
    """The MJCF file of a scene given by name (see `list_scenes()`) or as a path ending in .xml."""
    if str(scene).endswith(".xml"):
        path = Path(scene)
        if not path.is_file():
            raise MissingFileError(f"scene file not found: {path}")
        return path
    names = list_scenes()
    if scene not in names:
        raise UserError(f"unknown scene {scene!r}; available scenes: {names} or a path to an MJCF file ending in .xml")
    return scene_dir() / f"{scene}.xml"


def compose(vehicle: mujoco.MjSpec, scene: str | Path) -> mujoco.MjSpec:
    """The vehicle's MJCF spec with the scene attached (in place; also returned): the scene's
    worldbody, assets and lights under names prefixed "scene:", contacts and constraints on or off
    as the scene says, every other option the vehicle's."""
    path = scene_path(scene)
    try:
        world = mujoco.MjSpec.from_file(str(path))
    except Exception as err:  # MuJoCo's parser: a malformed file
        raise UserError(f"scene {path.name}: not a valid MJCF file ({err})") from None
    for body in world.worldbody.bodies:
        _check_static(body, path)
    flags = world.option.disableflags & _WORLD_FLAGS
    for name in _VEHICLE_OPTIONS:
        setattr(world.option, name, getattr(vehicle.option, name))
    for name in _SCENE_OPTIONS:
        setattr(vehicle.option, name, getattr(world.option, name))
    world.option.disableflags = (vehicle.option.disableflags & ~_WORLD_FLAGS) | flags
    vehicle.option.disableflags = world.option.disableflags
    has_latch = any(site.name == LATCH for site in world.sites)
    vehicle_sites = [site.name for site in vehicle.sites]
    vehicle.attach(world, frame=vehicle.worldbody.add_frame(), prefix=PREFIX)
    if has_latch and NOSE in vehicle_sites:
        vehicle.add_equality(name=LATCH, type=mujoco.mjtEq.mjEQ_WELD, objtype=mujoco.mjtObj.mjOBJ_SITE, name1=NOSE,
                             name2=PREFIX + LATCH, active=False, solref=LATCH_SOLREF)
    return vehicle


def _check_static(body, path: Path) -> None:
    if body.joints:
        raise UserError(f"scene {path.name}: body {body.name!r} has a joint; a scene holds static geometry only "
                        "(geoms, or bodies without joints)")
    for child in body.bodies:
        _check_static(child, path)


def contacts_enabled(model: mujoco.MjModel) -> bool:
    """Whether a compiled model collides: contacts and constraints both enabled."""
    return not (model.opt.disableflags & _WORLD_FLAGS)
