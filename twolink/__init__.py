"""twolink: a MuJoCo testbed for Busoniu, De Schutter & Babuska (ICARCV 2006)."""
import os as _os
import sys as _sys

__version__ = "0.1.0"


def _import_without_gl() -> None:
    """Import mujoco (and dm_control's renderer module, when installed) with no GL backend.

    Both pick their GL backend from ``MUJOCO_GL`` at import, and loading it (EGL) fails
    where libEGL is missing, and any MUJOCO_GL value they don't know is an error: so
    every command would fail, not only rendering. Importing them with
    ``MUJOCO_GL=disable`` defers the choice to the first renderer
    (:func:`twolink.render.use_gl_backend`); the user's MUJOCO_GL is kept for it.
    """
    fresh_mujoco = "mujoco" not in _sys.modules
    fresh_dm_control = "dm_control._render" not in _sys.modules
    saved = _os.environ.get("MUJOCO_GL")
    _os.environ["MUJOCO_GL"] = "disable"
    try:
        import mujoco  # noqa: F401
        try:
            from dm_control import _render
        except ImportError:  # dm_control is only needed by twolink.env
            _render = None
    finally:
        if saved is None:
            del _os.environ["MUJOCO_GL"]
        else:
            _os.environ["MUJOCO_GL"] = saved
    if fresh_mujoco:  # mujoco.Renderer and mujoco.GLContext pick the backend when called
        _sys.modules[mujoco.Renderer.__module__].gl_context.GLContext = _gl_context
        mujoco.GLContext = _gl_context
    if _render is not None and fresh_dm_control:
        _render.Renderer = _dm_control_context


def _gl_context(*args, **kwargs):
    from twolink.render import use_gl_backend

    return use_gl_backend()(*args, **kwargs)


def _dm_control_context(*args, **kwargs):
    from twolink.render import dm_control_context

    return dm_control_context(*args, **kwargs)


_import_without_gl()
