"""Offscreen rendering with MuJoCo: frames of a vehicle pose (Gymnasium's rgb_array) and videos of
recorded episodes (rendered in a child process with MUJOCO_GL set).

    python -m marinejax.render EPISODE.npz OUT_STEM   → prints the written MP4 or GIF path
"""

from __future__ import annotations

import copy
import os
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np

from marinejax.actuators import custom_text
from marinejax.errors import UserError


FIN_GEOMS = "marinejax:fin_geoms"  # MJCF custom text: "site:geom,geom site:geom ...", the geoms a fin site turns
# The water: colour of the fog (linear RGBA) and the distances (m from the camera) over which it
# thickens from clear to opaque; coastal water where a diver sees some 10-20 m.
WATER_RGBA = (0.03, 0.22, 0.3, 1.0)
FOG_START_M, FOG_END_M = 3.0, 30.0
TRAIL_STEPS = 120  # steps of the vehicle's past drawn as its trail (about every 4th)


def underwater(model: mujoco.MjModel) -> mujoco.MjModel:
    """Give a model (in place; also returned) the look of the water for rendering only: fog of
    WATER_RGBA from FOG_START_M to FOG_END_M (MuJoCo gives its fog distances in units of the model's
    extent), no light casts shadows (a sun through metres of water casts none sharp, and shadow maps
    over a 400 m seabed speckle), a dimmer, bluish headlight."""
    extent = float(model.stat.extent)
    model.vis.map.fogstart = FOG_START_M / extent
    model.vis.map.fogend = FOG_END_M / extent
    model.vis.rgba.fog[:] = WATER_RGBA
    model.vis.rgba.haze[:] = WATER_RGBA
    model.light_castshadow[:] = 0
    model.vis.headlight.ambient[:] = (0.3, 0.36, 0.4)
    model.vis.headlight.diffuse[:] = (0.55, 0.6, 0.6)
    return model


def fin_geoms(model: mujoco.MjModel) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """The vehicle's moving fins from its custom text `marinejax:fin_geoms`: (site name, geom ids,
    hinge axis in the body frame). A fin turns about x̂ × n̂ (n̂ the site's +z, its lift direction at
    positive deflection), so a positive deflection turns its leading edge towards n̂."""
    fins = []
    for entry in (custom_text(model, FIN_GEOMS) or "").split():
        site, _, geoms = entry.partition(":")
        site_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site)
        ids = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, g) for g in geoms.split(",")])
        if site_id < 0 or np.any(ids < 0) or not geoms:
            raise UserError(f"custom text {FIN_GEOMS!r}: entry {entry!r} must be <site>:<geom>[,<geom>...] with a site and "
                            f"geoms of the model")
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, model.site_quat[site_id])
        axis = np.cross([1.0, 0.0, 0.0], rot.reshape(3, 3)[:, 2])
        fins.append((site, ids, axis / np.linalg.norm(axis)))
    return fins


class FrameRenderer:
    """Offscreen RGB frames (height, width, 3) uint8 of a vehicle from its 'chase' camera, under
    water (`underwater`), with the target drawn as a red sphere, an optional reference path as small
    grey dots and the vehicle's trail as yellow ones; fins listed in the MJCF's `marinejax:fin_geoms`
    turn with their deflection when `frame` is given the actuator states.

    MuJoCo chooses its OpenGL backend when it is first imported: on a machine without a display,
    start Python with MUJOCO_GL=egl."""

    def __init__(self, model: mujoco.MjModel | str | Path, width: int = 640, height: int = 480, qpos_adr: int = 0):
        """model: the vehicle in its scene (`Vehicle.mj_model`, copied here) or a saved one (.mjb, .xml)."""
        self.model = underwater(_load_model(model))
        self.qpos_adr = int(qpos_adr)  # where the vehicle's free joint starts in qpos (Vehicle.sys.qpos_adr)
        self.data = mujoco.MjData(self.model)
        self.fins = fin_geoms(self.model)
        self.rest_quat = self.model.geom_quat.copy()
        for _, geoms, _ in self.fins:
            # the compiler marks a geom aligned with its body as sharing its frame and then ignores
            # geom_quat: moving fins must not
            self.model.geom_sameframe[geoms] = mujoco.mjtSameFrame.mjSAMEFRAME_NONE
        try:
            self.renderer = mujoco.Renderer(self.model, height=height, width=width)
        except Exception as err:  # no OpenGL context (GLFW without a display, missing EGL, ...)
            raise RuntimeError(
                f"MuJoCo could not create an OpenGL context for rendering ({type(err).__name__}: {err}); on a machine "
                "without a display set MUJOCO_GL=egl (or osmesa) before Python starts"
            ) from err
        self.renderer.scene.flags[mujoco.mjtRndFlag.mjRND_FOG] = 1

    def frame(self, position: np.ndarray, quaternion: np.ndarray, target: np.ndarray, path: np.ndarray | None = None,
              fin_angles: dict[str, float] | None = None, trail: np.ndarray | None = None) -> np.ndarray:
        """The frame of the vehicle at world `position` (m) and `quaternion` (w, x, y, z, body → world)
        with the target at world position `target` (m), the reference `path` (K, 3) and the vehicle's
        `trail` (J, 3: world positions it passed, m) if given, and the fins turned by `fin_angles`
        (site name → deflection, rad)."""
        for site, geoms, axis in self.fins:
            turn = np.zeros(4)
            mujoco.mju_axisAngle2Quat(turn, axis, float((fin_angles or {}).get(site, 0.0)))
            for g in geoms:
                mujoco.mju_mulQuat(self.model.geom_quat[g], turn, self.rest_quat[g])
        a = self.qpos_adr
        self.data.qpos[a : a + 3] = position
        self.data.qpos[a + 3 : a + 7] = quaternion
        mujoco.mj_forward(self.model, self.data)
        self.renderer.update_scene(self.data, camera="chase")
        scene = self.renderer.scene
        markers = ([(target, 0.04, (0.9, 0.1, 0.1, 0.9))] + [(p, 0.012, (0.8, 0.8, 0.8, 0.6)) for p in (path if path is not None else [])]
                   + [(p, 0.015, (1.0, 0.85, 0.2, 0.8)) for p in (trail if trail is not None else [])])
        for point, size, rgba in markers:
            if scene.ngeom >= scene.maxgeom:
                break
            mujoco.mjv_initGeom(scene.geoms[scene.ngeom], mujoco.mjtGeom.mjGEOM_SPHERE, np.array([size, 0, 0]),
                                np.asarray(point, dtype=np.float64), np.eye(3).flatten(), np.asarray(rgba, dtype=np.float32))
            scene.ngeom += 1
        return self.renderer.render().copy()

    def close(self) -> None:
        self.renderer.close()


def _load_model(model: mujoco.MjModel | str | Path) -> mujoco.MjModel:
    if isinstance(model, mujoco.MjModel):
        return copy.deepcopy(model)  # fins are turned in geom_quat: never in the caller's model
    if str(model).endswith(".mjb"):
        return mujoco.MjModel.from_binary_path(str(model))
    return mujoco.MjModel.from_xml_path(str(model))


def render_frames(model: mujoco.MjModel | str | Path, position: np.ndarray, quaternion: np.ndarray, targets: np.ndarray, qpos_adr: int = 0,
                  width: int = 640, height: int = 480, actuators: np.ndarray | None = None,
                  actuator_names: tuple[str, ...] = ()) -> list[np.ndarray]:
    """Frames of a recorded episode: world positions (T, 3, m), quaternions (T, 4), targets (T, 3, m),
    and the actuator states (T, n) named `actuator_names` (fins' in rad) if given; the targets,
    thinned to about 60 points, are drawn as the reference path, the last TRAIL_STEPS positions
    (every 4th) as the vehicle's trail."""
    renderer = FrameRenderer(model, width, height, qpos_adr)
    try:
        path = targets[:: max(1, len(targets) // 60)]
        fins = [(site, list(actuator_names).index(site)) for site, _, _ in renderer.fins if site in actuator_names]
        angles = [{site: float(a[i]) for site, i in fins} for a in actuators] if actuators is not None else [None] * len(position)
        return [renderer.frame(p, q, target, path, fin, position[max(0, t - TRAIL_STEPS) : t : 4])
                for t, (p, q, target, fin) in enumerate(zip(position, quaternion, targets, angles))]
    finally:
        renderer.close()


def write_video(frames: list[np.ndarray], fps: float, out_stem: Path) -> Path:
    """MP4 through imageio's ffmpeg when available, else an animated GIF with Pillow."""
    try:
        import imageio.v2 as imageio

        path = out_stem.with_suffix(".mp4")
        imageio.mimwrite(path, frames, fps=fps, codec="libx264", quality=7, macro_block_size=8)
        return path
    except Exception:  # no imageio or no ffmpeg encoder: fall back to GIF
        from PIL import Image

        path = out_stem.with_suffix(".gif")
        images = [Image.fromarray(f) for f in frames[::2]]
        images[0].save(path, save_all=True, append_images=images[1:], duration=int(2000 / fps), loop=0)
        return path


def render_video(model: mujoco.MjModel, position: np.ndarray, quaternion: np.ndarray, targets: np.ndarray, fps: float,
                 out_stem: Path, qpos_adr: int = 0, actuators: np.ndarray | None = None, actuator_names: tuple[str, ...] = ()) -> Path:
    """Render one episode of `model` (the vehicle in its scene, `Vehicle.mj_model`; arrays as
    `render_frames`) offscreen (MuJoCo, EGL) in a subprocess; returns the MP4 (or GIF) path.

    MuJoCo picks its OpenGL backend when it is first imported, so rendering runs in a child
    process started with MUJOCO_GL=egl (unless the caller set MUJOCO_GL).
    """
    data, model_file = out_stem.with_suffix(".npz"), out_stem.with_suffix(".mjb")
    mujoco.mj_saveModel(model, str(model_file), None)
    extra = {} if actuators is None else {"actuators": actuators, "actuator_names": np.array(actuator_names)}
    np.savez(data, position=position, quaternion=quaternion, targets=targets, fps=fps, model=str(model_file), qpos_adr=qpos_adr, **extra)
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    proc = subprocess.run([sys.executable, "-m", "marinejax.render", str(data), str(out_stem)],
                          env=env, capture_output=True, text=True)
    data.unlink(missing_ok=True)
    model_file.unlink(missing_ok=True)
    if proc.returncode != 0:
        raise RuntimeError(f"video rendering failed: {proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else proc.returncode}")
    return Path(proc.stdout.strip().splitlines()[-1])


def main(argv: list[str]) -> int:
    data = np.load(argv[0])
    actuators = (data["actuators"], tuple(str(n) for n in data["actuator_names"])) if "actuators" in data else (None, ())
    frames = render_frames(str(data["model"]), data["position"], data["quaternion"], data["targets"], int(data["qpos_adr"]),
                           actuators=actuators[0], actuator_names=actuators[1])
    print(write_video(frames, float(data["fps"]), Path(argv[1])))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
