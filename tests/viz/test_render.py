"""Headless EGL rendering: real frames, checked on their pixels; videos decoded back."""
import json
import os
import signal
import subprocess
import sys
import time

import mujoco
import numpy as np
import pytest

import twolink  # noqa: F401  (defers the GL backend to the first renderer)
from twolink.arm.parameters import TABLE_I, TS
from twolink.cli import main
from twolink.sim.rollout import Trajectory
from twolink.viz.render import (
    Renderer,
    diagnose,
    frame_count,
    sample_at,
    tip_positions,
    trajectory_frames,
)
from twolink.viz.video import read_video, write_video

W, H = 320, 240
STATES = [[-1.0, -3.0, 0, 0], [0.0, 0.0, 0, 0], [2.2, -1.1, 0, 0], [-2.8, 1.9, 0, 0],
          [0.7, 2.5, 0, 0]]


@pytest.fixture(scope="module")
def plain():
    with Renderer(width=W, height=H, ghost=False, overlay=False) as r:
        yield r


@pytest.fixture(scope="module")
def ghosted():
    with Renderer(width=W, height=H, ghost=True, overlay=False) as r:
        yield r


def _blue(img):       # link 2 (rgba 0.15, 0.45, 0.85)
    i = img.astype(int)
    return (i[..., 2] > 140) & (i[..., 2] - i[..., 0] > 90) & (i[..., 2] - i[..., 1] > 40)


def _purple(img):     # the ghost (0.62, 0.32, 0.92, alpha 0.4) over the light floor
    i = img.astype(int)
    return (i[..., 0] - i[..., 1] > 25) & (i[..., 2] - i[..., 1] > 45)


def _green(img):      # goal region (0.1, 0.75, 0.25, alpha 0.35)
    i = img.astype(int)
    return (i[..., 1] - i[..., 0] > 30) & (i[..., 1] - i[..., 2] > 30)


def _px(r, xy, z=0.0):
    xy = np.asarray(xy, dtype=float)
    return r.project(np.concatenate([xy, np.full(xy.shape[:-1] + (1,), z)], -1))


def test_frames_are_real_images(plain):
    img = plain.frame(STATES[0])
    assert img.shape == (H, W, 3) and img.dtype == np.uint8
    assert img.std() > 10                       # not blank
    assert _blue(img).sum() > 100               # the arm is in the picture


def test_camera_matrices_agree_with_the_model(plain):
    # The MJCF tip site and the planar forward kinematics project to the same pixel.
    for x in STATES:
        plain.frame(x)
        sid = mujoco.mj_name2id(plain.model, mujoco.mjtObj.mjOBJ_SITE, "link2_tip")
        site = plain.project(plain.data.site_xpos[sid])
        np.testing.assert_allclose(site, _px(plain, tip_positions(x)[1]), atol=1e-6)


@pytest.mark.parametrize("x", STATES)
def test_link2_tip_is_drawn_where_the_state_says(plain, x):
    img = plain.frame(x)
    elbow_px, tip_px = _px(plain, tip_positions(x))
    rows, cols = np.nonzero(_blue(img))
    pts = np.stack([cols, rows], -1) + 0.5
    far = pts[np.argmax(np.linalg.norm(pts - elbow_px, axis=1))]
    # The capsule's round end reaches one link radius beyond the tip.
    radius_px = np.linalg.norm(_px(plain, [0.008, 0.0]) - _px(plain, [0.0, 0.0]))
    direction = (tip_px - elbow_px) / np.linalg.norm(tip_px - elbow_px)
    assert np.linalg.norm(far - (tip_px + radius_px * direction)) < 3.0


def test_ghost_appears_where_requested(ghosted, plain):
    x, gx = np.array(STATES[0]), np.array([0.6, 1.2, 0, 0])
    img = ghosted.frame(x, ghost_x=gx)
    g_elbow, g_tip = _px(ghosted, tip_positions(gx), z=-0.012)
    mid = ((g_elbow + g_tip) / 2).round().astype(int)
    patch = lambda im: im[mid[1] - 2:mid[1] + 3, mid[0] - 2:mid[0] + 3]
    assert _purple(patch(img)).mean() > 0.8
    assert _purple(img).sum() > 150
    # Without a ghost (or with the ghost hidden under the arm) nothing purple is there.
    assert _purple(patch(plain.frame(x))).sum() == 0
    assert _purple(ghosted.frame(x, ghost_x=x)).sum() < 0.1 * _purple(img).sum()
    # The real arm is unchanged by the ghost.
    assert abs(int(_blue(img).sum()) - int(_blue(plain.frame(x)).sum())) < 20


def test_goal_region_is_marked(plain):
    img = plain.frame(STATES[0])
    c = _px(plain, [TABLE_I.l1 + TABLE_I.l2, 0.0], z=-0.028).round().astype(int)
    assert _green(img[c[1] - 3:c[1] + 4, c[0] - 3:c[0] + 4]).mean() > 0.9


def test_text_overlay_drawn_in_the_corner():
    with Renderer(width=W, height=H, overlay=True) as r:
        bare = r.frame(STATES[1])
        text = r.frame(STATES[1], lines=["t = 0.00 s", "tau = [+0.200, +0.100] Nm"])
    corner = (slice(0, 30), slice(0, 120))
    darker = text[corner].astype(int).sum(-1) < bare[corner].astype(int).sum(-1) - 150
    assert darker.mean() > 0.3                       # the dark box
    assert (text[corner].min(-1) > 200).sum() > 30   # white glyphs in it
    np.testing.assert_array_equal(text[100:], bare[100:])


def _line_trajectory(n=10):
    t = np.arange(n + 1) * TS
    x = np.zeros((n + 1, 4))
    x[:, 0] = np.linspace(3.0, 3.0 + 0.1 * n, n + 1)   # crosses +pi
    x[:, 0] = (x[:, 0] + np.pi) % (2 * np.pi) - np.pi
    u = np.tile([0.1, -0.05], (n, 1))
    r = np.full(n, -0.5)
    return Trajectory(t, x, u, r, np.stack([r, r], -1), "mujoco", "centralized")


def test_sample_at_hits_samples_and_interpolates_the_short_way():
    tr = _line_trajectory()
    x, u, r = sample_at(tr, tr.t)
    np.testing.assert_allclose(x, tr.x, atol=1e-12)
    xm, _, _ = sample_at(tr, tr.t[:-1] + TS / 2)
    step = np.angle(np.exp(1j * (xm[:, 0] - tr.x[:-1, 0])))
    np.testing.assert_allclose(step, 0.05, atol=1e-9)     # never the long way round


def test_real_time_frame_count(plain):
    assert frame_count(0.5, 20) == 11 and frame_count(0.5, 30) == 16 and frame_count(1, 8) == 9
    tr = _line_trajectory()
    frames = list(trajectory_frames(plain, [("a", tr, None)], fps=30))
    assert len(frames) == frame_count(tr.t[-1], 30)
    both = next(trajectory_frames(plain, [("a", tr, None), ("b", tr, None)], fps=20))
    assert both.shape == (H, 2 * W, 3)
    np.testing.assert_array_equal(both[:, :W], both[:, W:])


@pytest.mark.parametrize("ext", ["mp4", "gif"])
def test_video_decodes_to_expected_frames_and_size(plain, tmp_path, ext):
    # Distinct frames: a GIF merges identical consecutive frames (keeping their timing).
    frames = [plain.frame([0.3 * k, -0.2 * k, 0, 0])[60:180, 80:240] for k in range(12)]
    path = tmp_path / f"clip.{ext}"
    assert write_video(path, iter(frames), 20) == 12
    back = read_video(path)
    assert back.shape == (12, 120, 160, 3)
    err = np.abs(back.astype(int) - np.stack(frames).astype(int)).mean()
    assert err < 6
    assert [p.name for p in tmp_path.iterdir()] == [path.name]


def _render(capsys, *argv):
    code = main(["render", "--no-progress", *map(str, argv)])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_render_cli_writes_side_by_side_mp4(tmp_path, capsys):
    out = tmp_path / "pair.mp4"
    code, text, _ = _render(capsys, "--policy", "centralized", "--policy", "decentralized",
                            "--duration", 0.3, "--size", "96x64", "--json", "-o", out)
    assert code == 0
    rep = json.loads(text)
    assert rep["frames"] == 7 and rep["width"] == 192 and rep["ghost"] is True
    video = read_video(out)
    assert video.shape == (7, 64, 192, 3)
    assert video.std() > 10


def test_render_cli_gif_at_chosen_rate(tmp_path, capsys):
    out = tmp_path / "a.gif"
    code, text, _ = _render(capsys, "--duration", 0.5, "--fps", 10, "--size", "80x60",
                            "--no-ghost", "-o", out)
    assert code == 0 and "6 frames" in text
    assert read_video(out).shape == (6, 60, 80, 3)


@pytest.mark.parametrize("argv, message", [
    (["--size", "641x480"], "even frame size"),
    (["--size", "big"], "--size must look like"),
    (["-o", "{tmp}/v.avi"], "use .mp4 or .gif"),
    (["-o", "{tmp}/nodir/v.mp4"], "does not exist"),
    (["--fps", "0"], "frame rate"),
    (["--fps", "1e-9"], "frame rate must be in [1, 240] frames per second, got 1e-09"),
    (["--fps", "0.001", "-o", "{tmp}/v.gif"], "frame rate must be in [1, 240]"),
    (["--policy", "nope"], "unknown policy"),
    (["--policy", "centralized", "--policy", "decentralized", "--policy", "centralized"],
     "one or two --policy"),
    (["--speed", "1e-9", "--duration", "0.1"], "more than the limit of 18000"),
    (["--policy", "centralized", "--policy", "centralized"], "name the same policy"),
    (["--speed", "0"], "--speed must be a positive"),
    (["--duration", "500", "--size", "2048x2048"], "pixels"),
    (["--duration", "1e12"], "duration must be at most 3600 s"),
    (["--x0", "0", "0", "1e9", "0"], "beyond the bound"),
    (["--challenge", "nosuch"], "unknown challenge 'nosuch'"),
    (["--delay", "4"], "a delay of 4 samples is not shorter than the horizon of 4 samples"),
    (["--angle-noise-deg", "-1"], "--angle-noise-deg must be a non-negative number of degrees"),
])
def test_render_bad_input_one_line_no_file(argv, message, tmp_path, capsys):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    if "-o" not in argv:
        argv += ["-o", str(tmp_path / "v.mp4")]
    code, _, err = _render(capsys, "--duration", 0.2, *argv)
    assert code == 2 and err.count("\n") == 1 and message in err
    assert err.startswith("twolink render: error: ")
    assert list(tmp_path.iterdir()) == []


def test_render_cli_under_a_challenge_with_compensation(tmp_path, capsys):
    """The rendered run is the challenged, compensated one: its trajectory differs."""
    out = tmp_path / "c.gif"
    code, text, _ = _render(capsys, "--policy", "centralized_full", "--challenge", "medium",
                            "--compensate", "--seed", "2", "--duration", 0.3, "--fps", 10,
                            "--size", "80x60", "--no-ghost", "--json", "-o", out)
    assert code == 0
    rep = json.loads(text)
    assert rep["challenge"]["name"] == "medium" and rep["compensate"] and rep["seed"] == 2
    plain = tmp_path / "p.gif"
    assert _render(capsys, "--policy", "centralized_full", "--duration", 0.3, "--fps", 10,
                   "--size", "80x60", "--no-ghost", "-o", plain)[0] == 0
    a, b = read_video(out), read_video(plain)
    assert a.shape == b.shape == (4, 60, 80, 3)
    assert np.abs(a[-1].astype(int) - b[-1].astype(int)).sum() > 0   # another plant and loop


def test_render_to_a_directory_is_refused(tmp_path, capsys):
    (tmp_path / "v.mp4").mkdir()
    code, _, err = _render(capsys, "--duration", 0.2, "-o", tmp_path / "v.mp4")
    assert code == 2 and err.count("\n") == 1 and "is a directory" in err
    assert [p.name for p in tmp_path.iterdir()] == ["v.mp4"]


def test_frame_generator_refuses_an_oversized_video_up_front(plain):
    tr = _line_trajectory()
    frames = trajectory_frames(plain, [("a", tr, None)], fps=20, speed=1e-9)
    with pytest.raises(ValueError, match="more than the limit of 18000"):
        next(frames)


def test_gif_keeps_colours_that_appear_after_the_first_frame(tmp_path):
    frames = [np.full((48, 64, 3), 200, np.uint8) for _ in range(4)]
    frames[2][10:30, 20:40] = (158, 82, 235)           # the ghost's purple, frame 2 only
    frames[3][5:9, 5:60] = (38, 115, 217)              # link 2's blue, frame 3 only
    assert write_video(tmp_path / "c.gif", iter(frames), 10) == 4
    back = read_video(tmp_path / "c.gif").astype(int)
    assert np.abs(back - np.stack(frames).astype(int)).max() <= 4


def test_gif_frames_are_streamed_not_kept(plain, tmp_path):
    """Each frame is in the (temporary) file before the next one is asked for."""
    sizes = []

    def frames():
        for k in range(6):
            tmp = [p for p in tmp_path.iterdir() if p.name.startswith(".clip.")]
            sizes.append(tmp[0].stat().st_size if tmp else 0)
            yield plain.frame([0.3 * k, -0.2 * k, 0, 0])

    assert write_video(tmp_path / "clip.gif", frames(), 20) == 6
    assert all(b > a for a, b in zip(sizes[1:], sizes[2:])), sizes
    assert [p.name for p in tmp_path.iterdir()] == ["clip.gif"]


@pytest.mark.slow
@pytest.mark.parametrize("ext", ["mp4", "gif"])
def test_sigterm_during_render_leaves_no_file(tmp_path, ext):
    out = tmp_path / f"v.{ext}"
    proc = subprocess.Popen([sys.executable, "-m", "twolink.cli", "render", "--duration", "600",
                             "--size", "64x48", "--no-progress", "-o", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not any(p.stat().st_size > 0 for p in tmp_path.iterdir()):
            assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read()
            time.sleep(0.05)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 143, err                  # 128 + SIGTERM, as a shell reports it
    assert err.strip() == "twolink: terminated", err
    assert list(tmp_path.iterdir()) == []


def test_missing_egl_vendor_is_named_in_one_line(tmp_path):
    env = dict(os.environ, __EGL_VENDOR_LIBRARY_FILENAMES=str(tmp_path / "none.json"))
    res = subprocess.run([sys.executable, "-m", "twolink.cli", "render", "--duration", "0.1",
                          "--size", "64x48", "-o", str(tmp_path / "v.mp4")],
                         capture_output=True, text=True, env=env)
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1, res.stderr
    assert lines[0].startswith("twolink render: error: headless rendering is unavailable")
    assert "libEGL_mesa.so.0" in lines[0] and "libegl-mesa0" in lines[0]
    assert list(tmp_path.iterdir()) == []


def test_diagnose_names_a_wrong_backend(monkeypatch):
    monkeypatch.setenv("MUJOCO_GL", "glx")
    assert "MUJOCO_GL='glx'" in diagnose() and "egl" in diagnose()


def test_render_takes_a_folder_with_a_trailing_slash(tmp_path, capsys):
    """-o DIR/ writes the default name in DIR, made for it; under a missing folder it is
    one line and nothing is made."""
    folder = tmp_path / "videos"
    code, text, err = _render(capsys, "--duration", 0.2, "--size", "64x48", "--no-ghost",
                              "--json", "-o", f"{folder}/")
    assert code == 0, err
    assert json.loads(text)["path"] == str(folder / "centralized_mujoco.mp4")
    assert [p.name for p in folder.iterdir()] == ["centralized_mujoco.mp4"]
    code, _, err = _render(capsys, "--duration", 0.2, "-o", f"{tmp_path / 'no' / 'v'}/")
    assert code == 2 and err.count("\n") == 1 and "does not exist" in err
    assert [p.name for p in tmp_path.iterdir()] == ["videos"]


def test_render_logs_its_progress_when_stderr_is_a_file(tmp_path, monkeypatch):
    """With stderr a file the frame loop's bar is printed as lines, the last one at 100 %;
    --no-progress prints none."""
    log = tmp_path / "log.txt"
    with open(log, "w") as fh:
        monkeypatch.setattr("sys.stderr", fh)
        assert main(["render", "--duration", "0.3", "--size", "64x48", "--no-ghost",
                     "-o", str(tmp_path / "v.mp4")]) == 0
        assert main(["render", "--duration", "0.3", "--size", "64x48", "--no-ghost",
                     "--no-progress", "-o", str(tmp_path / "w.mp4")]) == 0
    lines = log.read_text().splitlines()
    assert lines and all(line.startswith("render v.mp4:") for line in lines), lines
    assert "100%" in lines[-1] and "7/7" in lines[-1], lines
