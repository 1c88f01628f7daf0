"""Plots of evaluated episodes: the vehicle's path against the target or reference, and the error."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def plot_paths(result: dict[str, np.ndarray], title: str, out: Path, episode: int = 0) -> Path:
    """PNG: the vehicle's path against the reference in 3-D and from the top (from the side over a
    seabed of blocks), and the error over time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p, r = result["position"][episode], result["target"][episode]
    fig = plt.figure(figsize=(14, 4.6))
    station = bool(np.allclose(r, r[0]))  # station keeping: the reference is one point
    ax = fig.add_subplot(1, 3, 1, projection="3d")
    ax.plot(*(r[:1].T if station else r.T), "r*" if station else "k--", lw=1, ms=10, label="target" if station else "reference")
    ax.plot(*p.T, "C0", lw=1.5, label="vehicle")
    ax.set_xlabel("x (m)"), ax.set_ylabel("y (m)"), ax.set_zlabel("z (m)")
    ax.legend(loc="upper left")
    ax2 = fig.add_subplot(1, 3, 2)
    boxes = result["layout_box"] if "layout" in result else np.zeros(0, bool)
    if boxes.any():  # a seabed of blocks (terrain following): the side view, the blocks' tops under the path
        for (x, _, z), size in zip(result["layout"][episode][boxes], result["layout_size"][boxes]):
            ax2.fill_between([x - size[0], x + size[0]], z - size[2], z + size[2], color="0.6", lw=0)
        ax2.plot(r[:, 0], r[:, 2], "k--", lw=1, label="reference")
        ax2.plot(p[:, 0], p[:, 2], "C0", lw=1.5, label="vehicle")
        ax2.set_ylim(min(r[:, 2].min(), p[:, 2].min()) - 4.0, max(r[:, 2].max(), p[:, 2].max()) + 1.0)
        ax2.set_xlim(p[:, 0].min() - 5.0, p[:, 0].max() + 5.0)
        ax2.set_xlabel("x (m)"), ax2.set_ylabel("z (m)"), ax2.set_title("side view, the seabed in grey")
        ax2.legend()
        return _finish(fig, result, episode, title, out)
    ax2.plot(r[:1, 0] if station else r[:, 0], r[:1, 1] if station else r[:, 1], "r*" if station else "k--", lw=1, ms=12,
             label="target" if station else "reference")
    ax2.plot(p[:, 0], p[:, 1], "C0", lw=1.5, label="vehicle")
    ax2.plot(p[0, 0], p[0, 1], "go", label="start")
    if "layout" in result:  # the episode's obstacles near the path, as circles of their radius (not the parked ones)
        span = np.ptp(np.concatenate([p[:, :2], r[:, :2]]), axis=0).max() + 5.0
        for (x, y, _), size in zip(result["layout"][episode], result["layout_size"]):
            if np.hypot(x - p[0, 0], y - p[0, 1]) < 2 * span:
                ax2.add_patch(plt.Circle((x, y), size[0], color="0.4", alpha=0.7))
    ax2.set_aspect("equal", adjustable="datalim")
    ax2.set_xlabel("x (m)"), ax2.set_ylabel("y (m)"), ax2.set_title("top view")
    ax2.legend()
    return _finish(fig, result, episode, title, out)


def _finish(fig, result: dict[str, np.ndarray], episode: int, title: str, out: Path) -> Path:
    """The error panel, the title, and the PNG written to `out`."""
    import matplotlib.pyplot as plt

    t = result["time"]
    ax3 = fig.add_subplot(1, 3, 3)
    for e in range(result["error"].shape[0]):
        ax3.plot(t, result["error"][e], color="0.8", lw=0.6)
    ax3.plot(t, result["error"][episode], "C0", lw=1.5, label=f"episode {episode}")
    ax3.plot(t, np.median(result["error"], axis=0), "C3", lw=1.2, label="median of episodes")
    ax3.set_yscale("log"), ax3.set_xlabel("time (s)"), ax3.set_ylabel("position error (m)")
    ax3.legend()
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def plot_sonar(result: dict[str, np.ndarray], azimuth_deg: np.ndarray, max_range: float, title: str, out: Path,
               episode: int = 0) -> Path:
    """PNG: the sonar's range image over an episode (time down, bearing across, range as colour)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ranges, t = result["sonar"][episode], result["time"]
    fig, ax = plt.subplots(figsize=(7, 5))
    image = ax.imshow(ranges, aspect="auto", origin="upper", cmap="viridis_r", vmin=0.0, vmax=max_range,
                      extent=(azimuth_deg[0], azimuth_deg[-1], t[-1], t[0]))
    ax.set_xlabel("bearing (°, positive to the left)"), ax.set_ylabel("time (s)"), ax.set_title(title)
    ax.invert_xaxis()  # left on the left, as the vehicle sees it
    fig.colorbar(image, ax=ax, label="range (m)")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
