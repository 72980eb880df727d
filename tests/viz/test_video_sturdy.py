"""Videos are never left half-written: a full disk or a failing ffmpeg is one error line
and no file, and the temporary file of a render killed by SIGKILL is removed by the next
render into the same folder."""
import errno
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import twolink  # noqa: F401  (defers the GL backend to the first renderer)
import twolink.viz.video as video
from twolink.cli import main
from twolink.viz.render import Renderer
from twolink.viz.video import TEMP_MARKER, read_video, remove_stale_temporaries, write_video

FRAMES = [np.full((48, 64, 3), 20 * i, np.uint8) for i in range(8)]


@pytest.fixture
def full_disk(monkeypatch):
    """Every video's temporary file is a link to /dev/full: each write fails with ENOSPC,
    as on a full disk (ffmpeg's too)."""
    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full")
    real = video.temporary_path

    def on_full_disk(path, pid=None):
        tmp = real(path, pid)
        os.symlink("/dev/full", tmp)
        return tmp

    monkeypatch.setattr(video, "temporary_path", on_full_disk)


def _render(capsys, *argv):
    code = main(["render", "--no-progress", "--duration", "0.2", "--size", "64x48",
                 *map(str, argv)])
    return code, capsys.readouterr().err


@pytest.mark.parametrize("ext", ["mp4", "gif"])
def test_render_onto_a_full_disk_fails_in_one_line_and_leaves_nothing(
        full_disk, tmp_path, capsys, ext):
    out = tmp_path / f"v.{ext}"
    code, err = _render(capsys, "-o", out)
    assert code == 2
    assert err.splitlines() == [err.strip()], err          # one line, nothing of ffmpeg's
    assert err.startswith(f"twolink render: error: cannot write video {out}: ")
    assert "No space left on device" in err
    assert list(tmp_path.iterdir()) == []


def test_a_full_disk_keeps_the_video_it_would_have_replaced(full_disk, tmp_path):
    out = tmp_path / "v.mp4"
    out.write_bytes(b"the old video")
    with pytest.raises(OSError, match="No space left on device") as exc:
        write_video(out, iter(FRAMES), 20)
    assert exc.value.errno == errno.ENOSPC or "ffmpeg failed" in str(exc.value)
    assert out.read_bytes() == b"the old video"
    assert [p.name for p in tmp_path.iterdir()] == ["v.mp4"]


def test_an_ffmpeg_exit_status_is_checked(tmp_path, monkeypatch):
    """An ffmpeg that takes every frame but exits with an error (as when the disk fills
    while it writes the trailer) is an error, not a truncated video."""
    fake = tmp_path / "ffmpeg"
    fake.write_text("#!/bin/sh\ncat > /dev/null\n"
                    "echo '[out#0/mp4 @ 0x1] Error writing trailer: No space left on device' >&2\n"
                    "exit 1\n")
    fake.chmod(0o755)
    import imageio_ffmpeg
    monkeypatch.setattr(imageio_ffmpeg, "get_ffmpeg_exe", lambda: str(fake))
    out = tmp_path / "videos"
    out.mkdir()
    with pytest.raises(OSError) as exc:
        write_video(out / "v.mp4", iter(FRAMES), 20)
    assert str(exc.value) == (f"cannot write video {out / 'v.mp4'}: ffmpeg failed (exit "
                              f"status 1): Error writing trailer: No space left on device")
    assert list(out.iterdir()) == []


@pytest.mark.parametrize("ext", ["mp4", "gif"])
def test_a_write_failing_midway_removes_the_temporary_file(tmp_path, ext):
    def frames():
        yield from FRAMES[:3]
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    with pytest.raises(OSError, match=f"cannot write video .*v.{ext}: No space left"):
        write_video(tmp_path / f"v.{ext}", frames(), 20)
    assert list(tmp_path.iterdir()) == []


def test_a_video_is_written_under_a_recognisable_temporary_name(tmp_path):
    seen = []

    def frames():
        for f in FRAMES:
            seen.extend(p.name for p in tmp_path.iterdir())
            yield f

    assert write_video(tmp_path / "v.gif", frames(), 20) == len(FRAMES)
    assert set(seen) == {f".v.gif{TEMP_MARKER}{os.getpid()}"}
    assert [p.name for p in tmp_path.iterdir()] == ["v.gif"]
    assert read_video(tmp_path / "v.gif").shape == (len(FRAMES), 48, 64, 3)


def test_only_temporary_videos_of_dead_processes_are_removed(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    pid = int(dead.stdout)
    stale = tmp_path / f".a.mp4{TEMP_MARKER}{pid}"
    alive = tmp_path / f".b.mp4{TEMP_MARKER}{os.getppid()}"
    mine = tmp_path / f".c.mp4{TEMP_MARKER}{os.getpid()}"
    other = tmp_path / f".d.mp4.{pid}"                     # not ours: never touched
    for p in (stale, alive, mine, other):
        p.write_bytes(b"x")
    assert remove_stale_temporaries(tmp_path) == [stale]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        p.name for p in (alive, mine, other))


def test_a_render_killed_by_sigkill_is_cleaned_up_by_the_next_render(tmp_path, capsys):
    out = tmp_path / "v.mp4"
    proc = subprocess.Popen([sys.executable, "-m", "twolink.cli", "render", "--duration", "600",
                             "--size", "64x48", "--no-progress", "-o", str(out)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    tmp = tmp_path / f".v.mp4{TEMP_MARKER}{proc.pid}"
    try:
        deadline = time.monotonic() + 120
        while not (tmp.exists() and tmp.stat().st_size > 0):
            assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read()
            time.sleep(0.05)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.stderr.close()
    assert proc.returncode == -signal.SIGKILL
    assert tmp.exists()                                    # SIGKILL cannot be caught
    code, err = _render(capsys, "-o", tmp_path / "w.gif")
    assert code == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["w.gif"]


@pytest.mark.parametrize("kwargs, error, message", [
    (dict(width=100_000), ValueError, "width must be from 1 to 4096 pixels, got 100000"),
    (dict(height=5000), ValueError, "height must be from 1 to 4096 pixels, got 5000"),
    (dict(width=0), ValueError, "width must be from 1 to 4096 pixels, got 0"),
    (dict(width="640"), TypeError, "width must be an int (pixels), got '640'"),
    (dict(height=480.0), TypeError, "height must be an int (pixels), got 480.0"),
])
def test_a_renderer_of_an_absurd_size_is_refused_before_any_allocation(
        monkeypatch, kwargs, error, message):
    import mujoco
    monkeypatch.setattr(mujoco, "Renderer", lambda *a, **k: pytest.fail("allocated"))
    with pytest.raises(error) as exc:
        Renderer(**kwargs)
    assert str(exc.value) == message
