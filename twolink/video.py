"""Writing frames to MP4 (H.264 through imageio-ffmpeg's bundled ffmpeg) or GIF (Pillow).

Videos are written atomically: frames go to a temporary file beside the target, which
is renamed over it only once the last frame is in, so an interrupted render leaves
nothing behind.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable

import numpy as np

from twolink.artifacts import atomic_path

FORMATS = ("mp4", "gif")


def video_format(path: os.PathLike) -> str:
    """``mp4`` or ``gif`` from the file name, or a clear ValueError."""
    ext = Path(path).suffix.lower().lstrip(".")
    if ext not in FORMATS:
        raise ValueError(f"cannot write video {path}: unsupported extension "
                         f"{'.' + ext if ext else '(none)'}; use .mp4 or .gif")
    return ext


def check_size(width: int, height: int, fmt: str = "mp4") -> None:
    if width < 16 or height < 16 or width > 4096 or height > 4096:
        raise ValueError(f"frame size must be between 16 and 4096 pixels, got {width}x{height}")
    if fmt == "mp4" and (width % 2 or height % 2):
        raise ValueError(f"H.264 (yuv420p) needs an even frame size, got {width}x{height}")


def check_fps(fps: float) -> None:
    if not np.isfinite(fps) or fps <= 0 or fps > 240:
        raise ValueError(f"frame rate must be in (0, 240] frames per second, got {fps}")


def write_video(path: os.PathLike, frames: Iterable[np.ndarray], fps: float, *,
                crf: int = 20) -> int:
    """Write RGB uint8 frames (H, W, 3) to ``path`` (.mp4 or .gif); returns the frame count."""
    path = Path(path)
    fmt = video_format(path)
    check_fps(fps)
    with atomic_path(path) as tmp:
        if fmt == "mp4":
            n = _write_mp4(tmp, frames, fps, crf)
        else:
            n = _write_gif(tmp, frames, fps)
    return n


def _write_mp4(path: Path, frames, fps: float, crf: int) -> int:
    import imageio_ffmpeg

    n, writer = 0, None
    try:
        for frame in frames:
            frame = np.ascontiguousarray(frame, dtype=np.uint8)
            if writer is None:
                h, w = frame.shape[:2]
                check_size(w, h, "mp4")
                writer = imageio_ffmpeg.write_frames(
                    str(path), (w, h), fps=fps, codec="libx264", pix_fmt_in="rgb24",
                    pix_fmt_out="yuv420p", macro_block_size=1, quality=None,
                    output_params=["-crf", str(crf), "-preset", "veryfast",
                                   "-movflags", "+faststart"],
                    ffmpeg_log_level="error")
                writer.send(None)
            writer.send(frame)
            n += 1
    finally:
        if writer is not None:
            writer.close()
    if n == 0:
        raise ValueError("no frames to write")
    return n


def _write_gif(path: Path, frames, fps: float) -> int:
    from PIL import Image

    images = [Image.fromarray(np.asarray(f, dtype=np.uint8)) for f in frames]
    if not images:
        raise ValueError("no frames to write")
    # One adaptive palette, from frames spread over the clip, keeps the file small and
    # the colours stable. Pillow merges identical consecutive frames into one longer
    # frame, so playback timing is kept.
    picks = np.linspace(0, len(images) - 1, min(len(images), 8)).round().astype(int)
    montage = Image.fromarray(np.concatenate([np.asarray(images[i]) for i in picks], 0))
    palette = montage.quantize(colors=255, method=Image.Quantize.MEDIANCUT)
    quantized = [im.quantize(palette=palette, dither=Image.Dither.NONE) for im in images]
    quantized[0].save(path, format="GIF", save_all=True, append_images=quantized[1:],
                      duration=round(1000.0 / fps), loop=0, optimize=False, disposal=1)
    return len(images)


def read_video(path: os.PathLike) -> np.ndarray:
    """All frames of a video as an array (N, H, W, 3), decoded with ffmpeg (for tests)."""
    import imageio.v3 as iio

    path = Path(path)
    if path.suffix.lower() == ".gif":
        return np.asarray(iio.imread(path, index=None, mode="RGB"))
    return np.stack(list(iio.imiter(path, plugin="FFMPEG")))
