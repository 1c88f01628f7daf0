"""Offscreen rendering of a recorded episode (run as a child process with MUJOCO_GL set).

    python -m marinejax.train.render EPISODE.npz OUT_STEM   → prints the written MP4 or GIF path
"""

from __future__ import annotations

import sys
from pathlib import Path

import mujoco
import numpy as np


def render_frames(model_path: str, qpos: np.ndarray, targets: np.ndarray, width: int = 640, height: int = 480) -> list[np.ndarray]:
    """RGB frames of the 'chase' camera with the target / reference point drawn as a red sphere and
    the reference path as small grey dots."""
    model = mujoco.MjModel.from_xml_path(model_path)
    data = mujoco.MjData(model)
    frames = []
    with mujoco.Renderer(model, height=height, width=width) as renderer:
        path = targets[:: max(1, len(targets) // 60)]
        for q, target in zip(qpos, targets):
            data.qpos[:7] = q
            mujoco.mj_forward(model, data)
            renderer.update_scene(data, camera="chase")
            scene = renderer.scene
            for point, size, rgba in [(target, 0.04, (0.9, 0.1, 0.1, 0.9))] + [(p, 0.012, (0.8, 0.8, 0.8, 0.6)) for p in path]:
                if scene.ngeom >= scene.maxgeom:
                    break
                mujoco.mjv_initGeom(scene.geoms[scene.ngeom], mujoco.mjtGeom.mjGEOM_SPHERE, np.array([size, 0, 0]),
                                    np.asarray(point, dtype=np.float64), np.eye(3).flatten(), np.asarray(rgba, dtype=np.float32))
                scene.ngeom += 1
            frames.append(renderer.render().copy())
    return frames


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


def main(argv: list[str]) -> int:
    data = np.load(argv[0])
    frames = render_frames(str(data["model"]), data["qpos"], data["targets"])
    print(write_video(frames, float(data["fps"]), Path(argv[1])))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
