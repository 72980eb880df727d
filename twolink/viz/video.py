"""Writing frames to MP4 (H.264 through imageio-ffmpeg's bundled ffmpeg) or GIF (Pillow).

Frames are streamed: each is encoded as it arrives and none is kept, so memory does not
grow with the length of a video. Videos are bounded (:data:`MAX_FRAMES` frames,
:data:`MAX_PIXELS` pixels in all; :func:`check_budget`) and written atomically: frames go
to a temporary file beside the target, ``.<name>.twolink-tmp-<pid>``, which is renamed
over it only once the last frame is in and the encoder has finished without error (for
MP4: ffmpeg's exit status is checked, so a full disk is an error, not a truncated
video). An error, Ctrl-C or SIGTERM removes the temporary file; a process killed outright
(SIGKILL) cannot, so every video written into a folder first removes the temporary
videos there of processes no longer running (:func:`remove_stale_temporaries`).
"""
from __future__ import annotations

import contextlib
import os
import re
import subprocess
import tempfile
from pathlib import Path
from typing import Iterable

import numpy as np

from twolink.artifacts import check_writable, sigterm_raises

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


#: Largest width or height of a frame, in pixels (a renderer's, a video's).
MAX_SIZE = 4096


def check_size(width: int, height: int, fmt: str = "mp4") -> None:
    """A ValueError unless a video frame of width x height is from 16 to :data:`MAX_SIZE`
    pixels each way (and even each way for H.264)."""
    if width < 16 or height < 16 or width > MAX_SIZE or height > MAX_SIZE:
        raise ValueError(f"frame size must be between 16 and {MAX_SIZE} pixels, got "
                         f"{width}x{height}")
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


#: The temporary file a video is written to before it is renamed: ``.<name>`` and this
#: marker followed by the writing process's id.
TEMP_MARKER = ".twolink-tmp-"
_TEMP_RE = re.compile(r"^\..+" + re.escape(TEMP_MARKER) + r"(\d+)$")


def temporary_path(path: os.PathLike, pid: int | None = None) -> Path:
    """The temporary file beside ``path`` that process ``pid`` (default: this one)
    writes the video to: ``.<name>.twolink-tmp-<pid>``."""
    path = Path(path)
    return path.with_name(f".{path.name}{TEMP_MARKER}{os.getpid() if pid is None else pid}")


def _running(pid: int) -> bool:
    """Whether a process ``pid`` exists (signal 0 probes it without sending anything)."""
    if pid <= 0:                                   # 0 would probe our process group
        return False
    try:
        os.kill(pid, 0)
    except PermissionError:                        # another user's process
        return True
    except (ProcessLookupError, OverflowError):    # none, or not a pid at all
        return False
    return True


def remove_stale_temporaries(folder: os.PathLike) -> list:
    """Delete the temporary videos (:func:`temporary_path`) in ``folder`` left by
    processes that are no longer running (a render killed by SIGKILL, which nothing can
    clean up after); returns the paths removed. Files of running processes, and files
    that cannot be removed, are left."""
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        m = _TEMP_RE.match(entry.name)
        if m and int(m.group(1)) != os.getpid() and not _running(int(m.group(1))):
            with contextlib.suppress(OSError):
                os.unlink(entry.path)
                removed.append(Path(entry.path))
    return removed


def write_video(path: os.PathLike, frames: Iterable[np.ndarray], fps: float, *,
                crf: int = 20) -> int:
    """Write RGB uint8 frames (H, W, 3) to ``path`` (.mp4 or .gif); returns the frame count.

    The frames go to :func:`temporary_path` beside ``path`` (stale temporary videos of
    dead processes there are removed first), renamed onto ``path`` only when the encoder
    has finished without error; on any error, Ctrl-C or SIGTERM the temporary file is
    removed and ``path`` is left as it was. A failed write (a full disk, ffmpeg exiting
    with an error) raises an OSError naming ``path``."""
    path = Path(path)
    fmt = video_format(path)
    check_fps(fps)
    check_writable(path)
    remove_stale_temporaries(path.parent if str(path.parent) else ".")
    tmp = temporary_path(path)
    with sigterm_raises():
        try:
            try:
                n = (_write_mp4(tmp, frames, fps, crf) if fmt == "mp4"
                     else _write_gif(tmp, frames, fps))
                if n and tmp.stat().st_size == 0:
                    raise OSError(f"{tmp.name} is empty")
                os.chmod(tmp, 0o666 & ~_umask())
                os.replace(tmp, path)
            except OSError as exc:
                reason = exc.strerror if exc.strerror else str(exc)
                error = OSError(f"cannot write video {path}: {reason}")
                error.errno = exc.errno                  # kept, out of the message
                raise error from None
        finally:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)
    return n


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _write_mp4(path: Path, frames, fps: float, crf: int) -> int:
    """Pipe the frames to imageio-ffmpeg's bundled ffmpeg (H.264, yuv420p) writing
    ``path``; an OSError with ffmpeg's last message when it cannot take a frame or exits
    with a non-zero status (e.g. on a full disk)."""
    import imageio_ffmpeg

    n, proc = 0, None
    with tempfile.TemporaryFile() as log:          # ffmpeg's messages; a file never blocks
        try:
            for frame in frames:
                frame = np.ascontiguousarray(frame, dtype=np.uint8)
                if proc is None:
                    h, w = frame.shape[:2]
                    check_size(w, h, "mp4")
                    proc = subprocess.Popen(
                        [imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-v", "error",
                         "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{w}x{h}",
                         "-r", f"{fps:.02f}", "-i", "-", "-an", "-vcodec", "libx264",
                         "-pix_fmt", "yuv420p", "-crf", str(crf), "-preset", "veryfast",
                         "-movflags", "+faststart", "-f", "mp4", str(path)],
                        stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=log,
                        start_new_session=True)   # Ctrl-C reaches us, not ffmpeg
                try:
                    proc.stdin.write(frame.data)
                except BrokenPipeError:           # ffmpeg quit: its status says why
                    break
                n += 1
            if proc is not None:
                with contextlib.suppress(BrokenPipeError):
                    proc.stdin.close()
                status = proc.wait()
                if status != 0:
                    log.seek(0)
                    lines = log.read().decode(errors="replace").strip().splitlines()
                    first = re.sub(r"^(\[[^]]*\]\s*)+", "", lines[0]) if lines else ""
                    raise OSError(f"ffmpeg failed (exit status {status})"
                                  + (f": {first.strip()}" if first.strip() else ""))
        finally:
            if proc is not None and proc.poll() is None:   # an error or Ctrl-C: stop it
                proc.kill()
                proc.wait()
            if proc is not None and not proc.stdin.closed:
                with contextlib.suppress(OSError):
                    proc.stdin.close()
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
