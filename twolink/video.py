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


def check_fps(fps: float) -> None:
    if not np.isfinite(fps) or fps <= 0 or fps > 240:
        raise ValueError(f"frame rate must be in (0, 240] frames per second, got {fps}")


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
    ``getdata``): one 256-colour palette from the first frame (median cut), then each
    frame quantized to it and written at once, cropped to where it differs from the
    previous one (disposal 1), so memory holds one frame whatever the length."""
    from PIL import GifImagePlugin, Image

    delay_ms = 10 * max(1, round(100.0 / fps))       # GIF delays are in centiseconds
    palette = previous = None
    n = 0
    with open(path, "wb", buffering=0) as fp:          # one write per frame, straight out
        for frame in frames:
            im = Image.fromarray(np.ascontiguousarray(frame, dtype=np.uint8))
            if palette is None:
                check_size(im.width, im.height, "gif")
                palette = im.quantize(colors=256, method=Image.Quantize.MEDIANCUT)
            q = im.quantize(palette=palette, dither=Image.Dither.NONE)
            index = np.asarray(q)
            if previous is None:
                header, _ = GifImagePlugin.getheader(q, info={"loop": 0})
                fp.write(b"".join(header))
                box = (0, 0, im.width, im.height)
            elif index.shape != previous.shape:
                raise ValueError(f"frame {n} is {im.width}x{im.height}, the first was "
                                 f"{previous.shape[1]}x{previous.shape[0]}")
            else:
                changed = index != previous
                rows, cols = np.flatnonzero(changed.any(1)), np.flatnonzero(changed.any(0))
                box = ((int(cols[0]), int(rows[0]), int(cols[-1]) + 1, int(rows[-1]) + 1)
                       if len(rows) else (0, 0, 1, 1))
            previous = index
            fp.write(b"".join(GifImagePlugin.getdata(q.crop(box), offset=box[:2],
                                                     duration=delay_ms, disposal=1)))
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
