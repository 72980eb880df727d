"""Offscreen rendering of the arm with MuJoCo's EGL backend.

The GL backend is chosen when the first renderer is made, not when mujoco is imported
(:func:`use_gl_backend`): ``MUJOCO_GL`` if set (egl, osmesa or glfw), else EGL, so the
same code renders on an NVIDIA GPU or, without one, on Mesa's software EGL device, and
everything that does not render works without any GL library. A frame shows the arm
from the top camera, the goal region (the tip's reach over the 5 deg band, and link 1's
band), optionally a translucent "ghost" arm (the simplified-model rollout of the same
policy, so the model mismatch is visible) and a text overlay with time, torques and
reward.
"""
from __future__ import annotations

import math

import mujoco
import numpy as np

from twolink.arm import mjcf
from twolink.arm.integrate import wrap_angle
from twolink.arm.parameters import (
    GOAL_ANGLE,
    TABLE_I,
    TS,
    ArmParameters,
    LinksParameters,
    as_links,
)
from twolink.arm.task import centralized_reward
from twolink.gl import (  # noqa: F401
    RenderError,
    close_at_exit,
    diagnose,
    gl_backend,
    release_current,
    unavailable_error,
    use_gl_backend,
)
from twolink.sim.rollout import Trajectory
from twolink.validate import pixels
from twolink.viz.video import MAX_SIZE

CAMERA = "top"
_GHOST_RGBA = (0.62, 0.32, 0.92, 0.40)
_GOAL_RGBA = (0.1, 0.75, 0.25, 0.35)
_GHOST_Z = -0.012
_GOAL_Z = -0.028


# --------------------------------------------------------------------------- model
def tip_positions(x, p: ArmParameters | LinksParameters = TABLE_I) -> np.ndarray:
    """Joint positions past the shoulder and the tip of states (..., 2N) in the plane:
    shape (..., N, 2), row k the far end of link k + 1 (for two links: elbow, tip)."""
    c = as_links(p)
    n = c.links
    x = np.asarray(x, dtype=float)
    if x.ndim == 0 or x.shape[-1] != 2 * n:
        raise ValueError(f"a {n}-link state has {2 * n} components, got shape {x.shape}")
    absolute = np.cumsum(x[..., :n], axis=-1)          # each link's angle to the x axis
    lengths = np.asarray(c.lengths)
    steps = np.stack([lengths * np.cos(absolute), lengths * np.sin(absolute)], -1)
    return np.cumsum(steps, axis=-2)


def goal_tip_radius(p: ArmParameters | LinksParameters = TABLE_I) -> float:
    """Largest distance of the tip from its goal (the stretched arm's reach, 0) over the
    5 deg angle band of every joint (its corners)."""
    c = as_links(p)
    corners = np.meshgrid(*[[-GOAL_ANGLE, GOAL_ANGLE]] * c.links, indexing="ij")
    angles = np.stack([a.ravel() for a in corners], -1)
    tips = tip_positions(np.concatenate([angles, np.zeros_like(angles)], -1), p)[:, -1]
    along = tips[:, 0]
    for length in c.lengths:                   # link by link, as the reach is summed
        along = along - length
    return float(np.max(np.hypot(along, tips[:, 1])))


def build_render_spec(p: ArmParameters | LinksParameters = TABLE_I, *, ghost: bool = False,
                      width: int = 640, height: int = 480,
                      samples: int = 0) -> mujoco.MjSpec:
    """The arm's MjSpec (two links or more) plus the goal-region marker and,
    optionally, a ghost arm of as many links."""
    c = as_links(p)
    n = c.links
    spec = mjcf.build_spec(p)
    spec.visual.global_.offwidth = max(spec.visual.global_.offwidth, width)
    spec.visual.global_.offheight = max(spec.visual.global_.offheight, height)
    # Seen from straight above, shadows add nothing but a 4096^2 shadow-map pass, which
    # dominates the frame time on Mesa's software device.
    spec.visual.quality.shadowsize = 0
    spec.visual.quality.offsamples = samples
    world = spec.worldbody
    reach = sum(c.lengths)
    # The floor fills any frame shape (wide side-by-side panels too), not just 4:3.
    spec.geom("floor").size = [reach * 4, reach * 4, 0.01]
    world.add_geom(name="goal_region", type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                   size=[goal_tip_radius(p), 0.001, 0], pos=[reach, 0, _GOAL_Z],
                   rgba=list(_GOAL_RGBA), contype=0, conaffinity=0, mass=0)
    for sign in (-1, 1):
        a = sign * GOAL_ANGLE
        half = reach / 2
        world.add_geom(name=f"goal_band_{'lo' if sign < 0 else 'hi'}",
                       type=mujoco.mjtGeom.mjGEOM_BOX, size=[half, 0.0012, 0.0005],
                       pos=[half * math.cos(a), half * math.sin(a), _GOAL_Z],
                       euler=[0, 0, a], rgba=[0.1, 0.6, 0.2, 0.6], contype=0,
                       conaffinity=0, mass=0)
    if ghost:
        parent = world
        joints, links = mjcf.joint_names(n), mjcf.link_names(n)
        starts = [(0, 0, _GHOST_Z)] + [(c.lengths[k - 1], 0, 0) for k in range(1, n)]
        for k, (length, pos) in enumerate(zip(c.lengths, starts)):
            body = parent.add_body(name=f"ghost_{links[k]}", pos=list(pos))
            body.mass = 1e-3
            body.inertia = [1e-6, 1e-6, 1e-6]
            body.explicitinertial = True
            body.add_joint(name=f"ghost_{joints[k]}", type=mujoco.mjtJoint.mjJNT_HINGE,
                           axis=[0, 0, 1])
            body.add_geom(name=f"ghost_{links[k]}_geom",
                          type=mujoco.mjtGeom.mjGEOM_CAPSULE, fromto=[0, 0, 0, length, 0, 0],
                          size=[0.008, 0, 0], rgba=list(_GHOST_RGBA), contype=0,
                          conaffinity=0, mass=0)
            parent = body
    return spec


# --------------------------------------------------------------------------- renderer
class Renderer:
    """Frames of the arm at given states, rendered offscreen through EGL.

    ``params`` is Table I's arm (the default), other two-link parameters or an N-link
    :class:`~twolink.arm.parameters.LinksParameters`; states then have 2N components.
    ``samples`` is the multisample anti-aliasing level (0 = off: on Mesa's software
    device 4x MSAA makes a frame about three times slower). ``width`` and ``height`` are
    ints from 1 to :data:`twolink.viz.video.MAX_SIZE` pixels, checked before anything is
    allocated (a TypeError or ValueError naming them). Use as a context manager (or
    call :meth:`close`) to free the GL context; one never closed is closed at interpreter
    exit (before EGL's display is terminated). The GL context is current on the calling
    thread only while a frame renders (:func:`twolink.gl.release_current`).
    """

    def __init__(self, *, width: int = 640, height: int = 480, ghost: bool = False,
                 overlay: bool = True, samples: int = 0,
                 params: ArmParameters | LinksParameters = TABLE_I):
        self._renderer = None
        self.width, self.height = pixels(width, "width", MAX_SIZE), pixels(height, "height",
                                                                          MAX_SIZE)
        self.ghost, self.overlay, self.params = bool(ghost), bool(overlay), params
        self.links = params.links
        self.model = build_render_spec(params, ghost=ghost, width=self.width,
                                       height=self.height, samples=samples).compile()
        self.data = mujoco.MjData(self.model)
        self._cam = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_CAMERA, CAMERA)
        self._renderer = None
        use_gl_backend()
        try:
            self._renderer = mujoco.Renderer(self.model, self.height, self.width)
        except Exception as exc:  # EGL/GL failures surface as several exception types
            raise unavailable_error(exc) from None
        self._release()
        close_at_exit(self)
        self._font = None

    def _release(self) -> None:
        release_current(getattr(self._renderer, "_gl_context", None))

    def close(self) -> None:
        """Free the GL context (made current first: its textures and buffers are freed
        through it)."""
        renderer = getattr(self, "_renderer", None)
        if renderer is not None:
            self._renderer = None
            context = getattr(renderer, "_gl_context", None)
            try:
                if context is not None:
                    context.make_current()
            except Exception:       # current on another thread: its resources go with it
                pass
            renderer.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass

    def _state(self, x, what: str) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        if x.shape != (2 * self.links,):
            raise ValueError(f"{what} of a {self.links}-link arm must have {2 * self.links} "
                             f"components, got shape {x.shape}")
        return x

    def _pose(self, x, ghost_x=None) -> None:
        n = self.links
        x = self._state(x, "state")
        self.data.qpos[:n] = x[:n]
        if self.ghost:
            g = x if ghost_x is None else self._state(ghost_x, "ghost state")
            self.data.qpos[n:2 * n] = g[:n]
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_camlight(self.model, self.data)

    def frame(self, x, *, ghost_x=None, lines=()) -> np.ndarray:
        """RGB frame (H, W, 3) of the arm at state ``x``, the ghost at ``ghost_x``."""
        if self._renderer is None:
            raise RenderError("renderer is closed")
        self._pose(x, ghost_x)
        self._renderer.update_scene(self.data, camera=CAMERA)
        try:
            img = self._renderer.render()
        finally:
            self._release()
        if self.overlay and lines:
            img = self._draw_text(img, lines)
        return img

    def project(self, points) -> np.ndarray:
        """Pixel coordinates (column, row) of world points (..., 3) in the top camera."""
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_camlight(self.model, self.data)
        pos = self.data.cam_xpos[self._cam]
        rot = self.data.cam_xmat[self._cam].reshape(3, 3)
        pc = (np.asarray(points, dtype=float) - pos) @ rot     # camera frame, looks along -z
        f = 0.5 * self.height / math.tan(math.radians(self.model.cam_fovy[self._cam]) / 2)
        col = 0.5 * self.width + f * pc[..., 0] / -pc[..., 2]
        row = 0.5 * self.height - f * pc[..., 1] / -pc[..., 2]
        return np.stack([col, row], -1)

    def _draw_text(self, img: np.ndarray, lines) -> np.ndarray:
        from PIL import Image, ImageDraw, ImageFont

        if self._font is None:
            self._font = ImageFont.load_default(size=max(9, self.height // 26))
        im = Image.fromarray(img)
        draw = ImageDraw.Draw(im, "RGBA")
        pad = max(2, self.height // 120)
        text = "\n".join(lines)
        box = draw.multiline_textbbox((pad * 2, pad * 2), text, font=self._font, spacing=pad)
        draw.rectangle((box[0] - pad, box[1] - pad, box[2] + pad, box[3] + pad),
                       fill=(20, 20, 20, 170))
        draw.multiline_text((pad * 2, pad * 2), text, font=self._font, fill=(255, 255, 255),
                            spacing=pad)
        return np.asarray(im)


# --------------------------------------------------------------------------- trajectories
def frame_count(duration: float, fps: float) -> int:
    """Frames of a real-time video of ``duration`` seconds: one per 1/fps, both ends in."""
    return int(math.floor(duration * fps + 1e-9)) + 1


def sample_at(traj: Trajectory, times) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """States (linearly interpolated, angles along the short way), held commands and the
    reward (15) of the last sample reached, at ``times`` (seconds); any number of links."""
    times = np.asarray(times, dtype=float)
    n = traj.x.shape[-1] // 2
    s = np.clip(times / TS, 0, traj.steps)
    k = np.minimum(np.floor(s + 1e-9).astype(int), traj.steps)
    nxt = np.minimum(k + 1, traj.steps)
    a = (s - k)[:, None]
    d = traj.x[nxt] - traj.x[k]
    d[:, :n] = wrap_angle(d[:, :n])
    x = traj.x[k] + a * d
    x[:, :n] = wrap_angle(x[:, :n])
    u = traj.u[np.minimum(k, traj.steps - 1)]
    r = np.concatenate([centralized_reward(traj.x[:1]), traj.r])[k]
    return x, u, r


def trajectory_frames(renderer: Renderer, panels, *, fps: float, speed: float = 1.0,
                      duration: float | None = None):
    """Yield frames of one or more panels side by side.

    ``panels`` is a sequence of ``(label, trajectory, ghost_trajectory_or_None)``. Frame i
    shows simulated time t = i * speed / fps: real time for speed 1. A video over the
    limits of :func:`twolink.viz.video.check_budget` is refused before the first frame.
    """
    panels = list(panels)
    if not panels:
        raise ValueError("nothing to render")
    duration = min(p[1].t[-1] for p in panels) if duration is None else duration
    from twolink.viz.video import check_budget
    check_budget(duration / speed * fps + 1, renderer.width * len(panels), renderer.height)
    times = np.arange(frame_count(duration / speed, fps)) * speed / fps
    sampled = [(label, sample_at(tr, times), None if g is None else sample_at(g, times)[0])
               for label, tr, g in panels]
    for i, t in enumerate(times):
        tiles = []
        for label, (x, u, r), gx in sampled:
            torques = ", ".join(f"{v:+.3f}" for v in u[i])
            lines = [label, f"t = {t:5.2f} s", f"tau = [{torques}] Nm", f"r = {r[i]:+.1f}"]
            tiles.append(renderer.frame(x[i], ghost_x=None if gx is None else gx[i],
                                        lines=lines))
        yield tiles[0] if len(tiles) == 1 else np.concatenate(tiles, axis=1)
