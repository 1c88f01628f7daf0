"""Offscreen rendering with MuJoCo: frames of a vehicle pose (Gymnasium's rgb_array) and videos of
recorded episodes (rendered in a child process with MUJOCO_GL set). An episode with a sonar
(`SonarTrace`) shows its fan of beams in the chase view and, beside it, the sonar's display: the
range image as a fan, bearing across and range up (`sonar_display`).

    python -m marinejax.render EPISODE.npz OUT_STEM   → prints the written MP4 or GIF path
"""

from __future__ import annotations

import copy
import dataclasses
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
ECHO_RGB = np.array([1.0, 0.8, 0.25])  # a sonar echo, in the chase view's beams and the display
FAN_RGB = np.array([0.03, 0.12, 0.18])  # the display's insonified water
RING_M = 5.0  # m between the display's range rings


@dataclasses.dataclass(frozen=True)
class SonarTrace:
    """A sonar's readings over an episode, to draw: ranges (T, beams, m) and hit (T, beams, bool)
    right to left across the fan; intensity (T, beams, 0-1) or None (every echo drawn at full
    strength); the fan's geometry: mount (3, m, body), directions (beams, 3, unit, body: the centre
    of each beam's vertical slice), azimuth (beams, rad, positive to the left) and max_range (m)."""

    ranges: np.ndarray
    hit: np.ndarray
    intensity: np.ndarray | None
    mount: np.ndarray
    directions: np.ndarray
    azimuth: np.ndarray
    max_range: float


def sonar_display(ranges: np.ndarray, hit: np.ndarray, intensity: np.ndarray | None, azimuth: np.ndarray, max_range: float,
                  size: int) -> np.ndarray:
    """One ping as a sonar display (size, size, 3) uint8: a fan with its apex at the bottom centre,
    bearing across (left on the left, as the vehicle sees it), range up to `max_range` at the top;
    each beam's echo a bright arc (its intensity, or full without one) one range bin thick, the
    water before it dim, its acoustic shadow behind it dark; range rings every RING_M m."""
    half = 0.5 * (azimuth[-1] - azimuth[0]) if len(azimuth) > 1 else np.radians(1.0)
    spacing = (azimuth[-1] - azimuth[0]) / (len(azimuth) - 1) if len(azimuth) > 1 else 2 * half
    y, x = np.mgrid[0:size, 0:size].astype(np.float64)
    scale = max_range / (size - 2.0)  # m per pixel
    dx, dy = (x - size / 2.0) * scale, (size - 1.0 - y) * scale
    r = np.hypot(dx, dy)
    bearing = np.arctan2(-dx, dy)  # positive to the left
    beam = np.clip(np.round((bearing - azimuth[0]) / spacing).astype(int), 0, len(azimuth) - 1)
    inside = (r <= max_range) & (np.abs(bearing) <= half + spacing / 2)
    echo_range, echoed = ranges[beam], hit[beam]
    strength = intensity[beam] if intensity is not None else np.ones_like(echo_range)
    thickness = max(2.0 * scale, 0.01 * max_range)
    image = np.where(inside[..., None], FAN_RGB, 0.0)
    image = np.where((inside & echoed & (r > echo_range + thickness))[..., None], 0.4 * FAN_RGB, image)  # shadow
    arc = inside & echoed & (np.abs(r - echo_range) <= thickness)
    image = np.where(arc[..., None], FAN_RGB + strength[..., None] * (ECHO_RGB - FAN_RGB), image)
    rings = inside & (np.abs(r / RING_M - np.round(r / RING_M)) * RING_M < 0.5 * scale) & (r > 0.5 * RING_M)
    image = np.where((rings & ~arc)[..., None], image + 0.25, image)
    return (255 * np.clip(image, 0.0, 1.0)).astype(np.uint8)


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
              fin_angles: dict[str, float] | None = None, trail: np.ndarray | None = None,
              beams: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """The frame of the vehicle at world `position` (m) and `quaternion` (w, x, y, z, body → world)
        with the target at world position `target` (m), the reference `path` (K, 3) and the vehicle's
        `trail` (J, 3: world positions it passed, m) if given, the fins turned by `fin_angles`
        (site name → deflection, rad), and a sonar's `beams` if given: (origin (3,), ends (B, 3),
        strength (B,): 0 for a beam without an echo, drawn faint), world, m."""
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
        if beams is not None:
            origin, ends, strength = beams
            for end, k in zip(ends, strength):
                if scene.ngeom >= scene.maxgeom:
                    break
                rgba = np.append(ECHO_RGB, 0.25 + 0.65 * k) if k > 0 else np.array([0.6, 0.7, 0.75, 0.12])
                geom = scene.geoms[scene.ngeom]
                mujoco.mjv_initGeom(geom, mujoco.mjtGeom.mjGEOM_LINE, np.zeros(3), np.zeros(3), np.eye(3).flatten(), rgba.astype(np.float32))
                mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_LINE, 1.5, np.asarray(origin, np.float64), np.asarray(end, np.float64))
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
                  actuator_names: tuple[str, ...] = (), sonar: SonarTrace | None = None) -> list[np.ndarray]:
    """Frames of a recorded episode: world positions (T, 3, m), quaternions (T, 4), targets (T, 3, m),
    and the actuator states (T, n) named `actuator_names` (fins' in rad) if given; the targets,
    thinned to about 60 points, are drawn as the reference path, the last TRAIL_STEPS positions
    (every 4th) as the vehicle's trail. With a `sonar`, each frame shows its beams (to their echo,
    or faint to the maximum range) and has the sonar's display (`sonar_display`, height × height)
    to the right of the chase view: frames (height, width + height, 3)."""
    renderer = FrameRenderer(model, width, height, qpos_adr)
    try:
        path = targets[:: max(1, len(targets) // 60)]
        fins = [(site, list(actuator_names).index(site)) for site, _, _ in renderer.fins if site in actuator_names]
        angles = [{site: float(a[i]) for site, i in fins} for a in actuators] if actuators is not None else [None] * len(position)
        frames = []
        for t, (p, q, target, fin) in enumerate(zip(position, quaternion, targets, angles)):
            beams = None
            if sonar is not None:
                rot = np.zeros(9)
                mujoco.mju_quat2Mat(rot, np.asarray(q, np.float64))
                rot = rot.reshape(3, 3)
                origin = p + rot @ sonar.mount
                strength = np.where(sonar.hit[t], 1.0 if sonar.intensity is None else np.maximum(sonar.intensity[t], 0.05), 0.0)
                beams = (origin, origin + (sonar.directions @ rot.T) * sonar.ranges[t][:, None], strength)
            frame = renderer.frame(p, q, target, path, fin, position[max(0, t - TRAIL_STEPS) : t : 4], beams)
            if sonar is not None:
                display = sonar_display(sonar.ranges[t], sonar.hit[t], None if sonar.intensity is None else sonar.intensity[t],
                                        sonar.azimuth, sonar.max_range, height)
                frame = np.concatenate([frame, display], axis=1)
            frames.append(frame)
        return frames
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
                 out_stem: Path, qpos_adr: int = 0, actuators: np.ndarray | None = None, actuator_names: tuple[str, ...] = (),
                 sonar: SonarTrace | None = None) -> Path:
    """Render one episode of `model` (the vehicle in its scene, `Vehicle.mj_model`; arrays as
    `render_frames`) offscreen (MuJoCo, EGL) in a subprocess; returns the MP4 (or GIF) path.

    MuJoCo picks its OpenGL backend when it is first imported, so rendering runs in a child
    process started with MUJOCO_GL=egl (unless the caller set MUJOCO_GL).
    """
    data, model_file = out_stem.with_suffix(".npz"), out_stem.with_suffix(".mjb")
    mujoco.mj_saveModel(model, str(model_file), None)
    extra = {} if actuators is None else {"actuators": actuators, "actuator_names": np.array(actuator_names)}
    if sonar is not None:
        extra.update({f"sonar_{k}": v for k, v in dataclasses.asdict(sonar).items() if v is not None})
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
    sonar = None
    if "sonar_ranges" in data:
        fields = {f.name: data[f"sonar_{f.name}"] if f"sonar_{f.name}" in data else None for f in dataclasses.fields(SonarTrace)}
        sonar = SonarTrace(**{**fields, "max_range": float(fields["max_range"])})
    frames = render_frames(str(data["model"]), data["position"], data["quaternion"], data["targets"], int(data["qpos_adr"]),
                           actuators=actuators[0], actuator_names=actuators[1], sonar=sonar)
    print(write_video(frames, float(data["fps"]), Path(argv[1])))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
