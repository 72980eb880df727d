"""Writing frames to MP4 (H.264 through imageio-ffmpeg's bundled ffmpeg) or GIF (Pillow).

Frames are streamed: each is encoded as it arrives and none is kept, so memory does not
grow with the length of a video. Videos are bounded (:data:`MAX_FRAMES` frames,
:data:`MAX_PIXELS` pixels in all; :func:`check_budget`) and written atomically: frames go
to a temporary file beside the target, which is renamed over it only once the last
frame is in, so an interrupted render (error, Ctrl-C, SIGTERM) leaves nothing behind.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable

import numpy as np

from twolink.artifacts import atomic_path

FORMATS = ("mp4", "gif")
#: Most frames in one video: 15 minutes at 20 frames per second.
MAX_FRAMES = 18_000
#: Most pixels in one video, all frames together: 18 000 frames of 640x480.
MAX_PIXELS = MAX_FRAMES * 640 * 480


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


#: Frame rates a video may have: below one frame per second a player shows nothing (and
#: a GIF's frame delay overflows), above 240 no display follows.
MIN_FPS, MAX_FPS = 1.0, 240.0


def check_fps(fps: float) -> None:
    if not np.isfinite(fps) or not MIN_FPS <= fps <= MAX_FPS:
        raise ValueError(f"frame rate must be in [{MIN_FPS:g}, {MAX_FPS:g}] frames per "
                         f"second, got {fps:g}")


def check_budget(frames: float, width: int, height: int) -> None:
    """A clear ValueError if a video of ``frames`` frames of width x height is over
    :data:`MAX_FRAMES` or :data:`MAX_PIXELS`; call it before rendering anything."""
    if not frames <= MAX_FRAMES:            # also catches NaN and inf
        raise ValueError(f"the video would have {frames:.4g} frames, more than the limit of "
                         f"{MAX_FRAMES}; lower the duration or --fps, or raise --speed")
    if frames * width * height > MAX_PIXELS:
        raise ValueError(f"the video would have {frames * width * height:.3g} pixels "
                         f"({frames:.0f} frames of {width}x{height}), more than the limit of "
                         f"{MAX_PIXELS:.3g}; lower the size, the duration or --fps")


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
    """Stream frames into an animated GIF with Pillow's GIF helpers (``getheader``,
    ``getdata``): each frame is cropped to the box where it differs from the previous
    one, quantized to its own 256-colour table (median cut) and written at once
    (disposal 1 keeps the rest), so memory holds one frame whatever the length."""
    from PIL import GifImagePlugin, Image

    delay_ms = 10 * max(1, round(100.0 / fps))       # GIF delays are in centiseconds
    previous = None
    n = 0
    with open(path, "wb", buffering=0) as fp:          # one write per frame, straight out
        for frame in frames:
            frame = np.ascontiguousarray(frame, dtype=np.uint8)
            if previous is None:
                check_size(frame.shape[1], frame.shape[0], "gif")
                box = (0, 0, frame.shape[1], frame.shape[0])
            elif frame.shape != previous.shape:
                raise ValueError(f"frame {n} has shape {frame.shape}, the first one "
                                 f"{previous.shape}")
            else:
                changed = np.any(frame != previous, axis=-1)
                rows, cols = np.flatnonzero(changed.any(1)), np.flatnonzero(changed.any(0))
                box = ((int(cols[0]), int(rows[0]), int(cols[-1]) + 1, int(rows[-1]) + 1)
                       if len(rows) else (0, 0, 1, 1))
            crop = Image.fromarray(frame[box[1]:box[3], box[0]:box[2]])
            q = crop.quantize(colors=256, method=Image.Quantize.MEDIANCUT,
                              dither=Image.Dither.NONE)
            if previous is None:
                header, _ = GifImagePlugin.getheader(q, info={"loop": 0})
                fp.write(b"".join(header))
            fp.write(b"".join(GifImagePlugin.getdata(q, offset=box[:2], duration=delay_ms,
                                                     disposal=1, include_color_table=True)))
            previous = frame
            n += 1
        fp.write(b";")                                   # GIF trailer
    if n == 0:
        raise ValueError("no frames to write")
    return n


def read_video(path: os.PathLike) -> np.ndarray:
    """All frames of a video as an array (N, H, W, 3), decoded with ffmpeg (for tests)."""
    import imageio.v3 as iio

    path = Path(path)
    if path.suffix.lower() == ".gif":
        return np.asarray(iio.imread(path, index=None, mode="RGB"))
    return np.stack(list(iio.imiter(path, plugin="FFMPEG")))
