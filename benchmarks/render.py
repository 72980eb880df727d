"""Rendering benchmarks: frames per second through the package's renderer against a bare
``mujoco.Renderer`` of the same arm, and the MP4 encoding time (imageio-ffmpeg, H.264)."""
from __future__ import annotations

import tempfile
from pathlib import Path

import mujoco
import numpy as np

from benchmarks.common import Row, best_time
from twolink.arm import mjcf
from twolink.viz.render import CAMERA, Renderer, build_render_spec
from twolink.viz.video import read_video, write_video

SECTION = "rendering"
SIZES = ((320, 240), (640, 480))


def _poses(n: int) -> np.ndarray:
    """``n`` arm states sweeping both joints, so every frame differs."""
    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return np.stack([t, -2 * t, np.zeros(n), np.zeros(n)], -1)


def bare_fps(model: mujoco.MjModel, width: int, height: int, frames: int,
             repeats: int) -> float:
    """Frames per second of a bare ``mujoco.Renderer`` of ``model`` (top camera)."""
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    data = mujoco.MjData(model)
    poses = _poses(frames)
    with mujoco.Renderer(model, height, width) as renderer:
        def run():
            for x in poses:
                data.qpos[:2] = x[:2]
                mujoco.mj_kinematics(model, data)
                mujoco.mj_camlight(model, data)
                renderer.update_scene(data, camera=CAMERA)
                img = renderer.render()
            return img
        run()                                               # first frame sets up GL
        t, img = best_time(run, repeats)
    if img.shape != (height, width, 3):
        raise RuntimeError(f"bare renderer returned a frame of shape {img.shape}")
    return frames / t


def package_fps(width: int, height: int, frames: int, repeats: int, *,
                ghost: bool = False, overlay: bool = False) -> tuple[float, list]:
    """Frames per second of :class:`twolink.viz.render.Renderer` (goal region drawn; the ghost
    arm and the text overlay optional), and the frames of the last run."""
    poses = _poses(frames)
    lines = ("t = 0.00 s", "tau = [+0.00, +0.00] Nm") if overlay else ()
    with Renderer(width=width, height=height, ghost=ghost, overlay=overlay) as r:
        def run():
            return [r.frame(x, ghost_x=x[::-1] if ghost else None, lines=lines)
                    for x in poses]
        run()
        t, out = best_time(run, repeats)
    if out[-1].shape != (height, width, 3):
        raise RuntimeError(f"package renderer returned a frame of shape {out[-1].shape}")
    return frames / t, out


def bench_render(*, frames: int = 20, repeats: int = 2) -> tuple[list[Row], dict]:
    rows, summary = [], {}
    video_frames = None
    for width, height in SIZES:
        sec = f"{SECTION}: {width}x{height}"
        plain = bare_fps(mjcf.build_model(), width, height, frames, repeats)
        bare = bare_fps(build_render_spec(width=width, height=height).compile(), width, height,
                        frames, repeats)
        pkg, out = package_fps(width, height, frames, repeats)
        full, _ = package_fps(width, height, frames, repeats, ghost=True, overlay=True)
        rows += [
            Row(sec, "bare mujoco.Renderer, plain MJCF", plain, "frames/s",
                "models/ arm, MuJoCo's default shadows and 4x multisampling"),
            Row(sec, "bare mujoco.Renderer, same scene", bare, "frames/s",
                "the package's render model (no shadow map, no multisampling)"),
            Row(sec, "twolink Renderer", pkg, "frames/s", "arm + goal region"),
            Row(sec, "twolink Renderer, ghost + overlay", full, "frames/s",
                "second arm + text drawn with Pillow"),
            Row(sec, "twolink / bare, same scene", pkg / bare, "x", "1 = no overhead"),
            Row(sec, "twolink / bare, plain MJCF", pkg / plain, "x",
                "what the package's render settings buy"),
        ]
        summary[f"{width}x{height}"] = {"plain": plain, "bare": bare, "package": pkg,
                                        "ghost_overlay": full}
        video_frames = out
    width, height = SIZES[-1]
    sec = f"{SECTION}: video encoding"
    clip = video_frames * max(1, 60 // len(video_frames))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.mp4"
        t, n = best_time(lambda: write_video(path, clip, 30.0), repeats)
        size = path.stat().st_size
        back = read_video(path)
    if back.shape[0] != n or back.shape[1:] != (height, width, 3):
        raise RuntimeError(f"encoded video decodes to shape {back.shape}")
    rows += [
        Row(sec, f"mp4 encoding {width}x{height}", n / t, "frames/s",
            f"{n} frames, H.264 crf 20 veryfast via imageio-ffmpeg"),
        Row(sec, "mp4 encoding time per frame", t / n * 1e3, "ms",
            f"{size / n / 1024:.1f} KiB per frame"),
    ]
    summary["encode_fps"] = n / t
    return rows, summary
