"""The GL backend of mujoco and dm_control, deferred to the first renderer.

mujoco (and dm_control's renderer module, when installed) pick their GL backend from
``MUJOCO_GL`` at import; loading it (EGL) fails where libEGL is missing, and a MUJOCO_GL
value they don't know is an error, so every use of the arm would fail, not only
rendering. ``import twolink`` calls :func:`install`: whoever imports mujoco next, it
executes with ``MUJOCO_GL=disable`` and gets stand-ins that bind the backend
(:func:`use_gl_backend`) at the first ``mujoco.Renderer``, ``mujoco.GLContext`` or
dm_control render context. The user's MUJOCO_GL is kept for it.
"""
from __future__ import annotations

import atexit
import contextlib
import ctypes
import glob
import importlib
import os
import sys
import threading
import weakref

from twolink._imports import around_import


class RenderError(RuntimeError):
    """Headless rendering is impossible on this machine; the message says why in one line."""


# --------------------------------------------------------------------------- GL backend
#: MUJOCO_GL values a renderer can use: mujoco's GLContext module and dm_control's
#: render-context class for each.
_BACKENDS = {
    "egl": ("mujoco.egl", "dm_control._render.pyopengl.egl_renderer", "EGLContext"),
    "osmesa": ("mujoco.osmesa", "dm_control._render.pyopengl.osmesa_renderer",
               "OSMesaContext"),
    "glfw": ("mujoco.glfw", "dm_control._render.glfw_renderer", "GLFWContext"),
}


def gl_backend() -> str:
    """The GL backend renderers use: ``MUJOCO_GL`` when set, else ``egl``."""
    return (os.environ.get("MUJOCO_GL") or "egl").strip().lower()


def unavailable_error(exc: BaseException | None = None) -> RenderError:
    """The RenderError of this machine: :func:`diagnose`'s line."""
    return RenderError(f"headless rendering is unavailable: {diagnose(exc)}")


def use_gl_backend():
    """Bind mujoco's offscreen GL backend (:func:`gl_backend`); return its GLContext class.

    This module imports mujoco with ``MUJOCO_GL=disable`` so that importing never
    touches a GL library, and leaves a stand-in that calls this at the first
    ``mujoco.Renderer`` or ``mujoco.GLContext``: this completes what mujoco's
    ``gl_context`` module would have done at import. Raises :class:`RenderError` with
    :func:`diagnose`'s line.
    """
    import mujoco

    name = gl_backend()
    if name not in _BACKENDS or (name == "glfw" and not os.environ.get("DISPLAY")
                                 and not os.environ.get("WAYLAND_DISPLAY")):
        raise unavailable_error()           # before GLFW prints warnings of its own
    try:
        context = importlib.import_module(_BACKENDS[name][0]).GLContext
    except Exception as exc:  # a missing library surfaces as several exception types
        raise unavailable_error(exc) from None
    sys.modules[mujoco.Renderer.__module__].gl_context.GLContext = context
    mujoco.GLContext = context
    return context


def dm_control_context(*args, **kwargs):
    """dm_control's render context on :func:`gl_backend` (what ``physics.render`` makes).

    The first import installs this as ``dm_control._render.Renderer``, so a dm_control
    environment picks its GL backend at its first render, as :class:`Renderer` does.
    """
    from dm_control import _render

    use_gl_backend()
    name = gl_backend()
    try:
        module, cls = _BACKENDS[name][1:]
        context = getattr(importlib.import_module(module), cls)
    except Exception as exc:
        raise unavailable_error(exc) from None
    _render.Renderer, _render.BACKEND = context, name
    _render.USING_GPU = name in ("egl", "glfw")
    try:
        return context(*args, **kwargs)
    except Exception as exc:
        raise unavailable_error(exc) from None


# --------------------------------------------------------------------------- context lifetime
def release_current(context) -> None:
    """Make no GL context current on this thread if mujoco's GLContext ``context`` is.

    mujoco's ``Renderer.render`` makes its context current and leaves it so; a context
    left current on a thread is still current at interpreter exit, after mujoco's EGL
    module has terminated the display (its ``atexit`` handler), and freeing it then fails
    (an ``EGLError`` printed at exit) or crashes. Every render makes it current again.
    EGL and GLFW contexts are released; others (OSMesa) are left as they are."""
    handle = getattr(context, "_context", None)
    module = sys.modules.get(type(context).__module__)
    if not handle or module is None:
        return
    if module.__name__ == "mujoco.egl":
        egl = module.EGL
        current = egl.eglGetCurrentContext()
        if current and getattr(current, "address", None) == handle.address:
            egl.eglMakeCurrent(module.EGL_DISPLAY, egl.EGL_NO_SURFACE, egl.EGL_NO_SURFACE,
                               egl.EGL_NO_CONTEXT)
    elif module.__name__ == "mujoco.glfw":
        glfw = module.glfw
        if glfw.get_current_context() == handle:
            glfw.make_context_current(None)


_open_at_exit: weakref.WeakSet = weakref.WeakSet()
_exit_lock = threading.Lock()
_exit_registered = False


def close_at_exit(resource) -> None:
    """Call ``resource.close()`` at interpreter exit unless it is gone by then (a weak
    reference). Call it once the resource's GL context exists: ``atexit`` runs handlers
    last in, first out, so these closes run before mujoco's ``eglTerminate``, registered
    when the first EGL context was made."""
    global _exit_registered
    with _exit_lock:
        _open_at_exit.add(resource)
        if not _exit_registered:
            atexit.register(close_all_at_exit)
            _exit_registered = True


def close_all_at_exit() -> None:
    """Close every resource :func:`close_at_exit` holds (the ``atexit`` handler)."""
    for resource in list(_open_at_exit):
        try:
            resource.close()
        except Exception:       # at exit: nothing left to report to
            pass
    _open_at_exit.clear()


# --------------------------------------------------------------------------- diagnosis
def _loadable(name: str) -> bool:
    try:
        ctypes.CDLL(name)
        return True
    except OSError:
        return False


def _egl_vendor_files() -> list[str]:
    listed = os.environ.get("__EGL_VENDOR_LIBRARY_FILENAMES")
    if listed:
        return [f for f in listed.split(":") if os.path.isfile(f)]
    dirs = os.environ.get("__EGL_VENDOR_LIBRARY_DIRS",
                          "/etc/glvnd/egl_vendor.d:/usr/share/glvnd/egl_vendor.d")
    return [f for d in dirs.split(":") for f in glob.glob(os.path.join(d, "*.json"))]


def diagnose(exc: BaseException | None = None) -> str:
    """One line naming what stops headless rendering on the chosen backend
    (:func:`gl_backend`): a backend MuJoCo does not know, a missing library (EGL's
    libEGL, vendor file and Mesa driver; OSMesa's libOSMesa; GLFW's library and an X
    display), or the backend's own error."""
    fix = "run scripts/install-system-deps.sh as root, or apt-get install"
    name = gl_backend()
    if name not in _BACKENDS:
        return (f"MUJOCO_GL={os.environ.get('MUJOCO_GL', '')!r} is not a rendering "
                f"backend; use egl (headless, the default), osmesa or glfw")
    if name == "osmesa":
        return _diagnose_osmesa(exc)
    if name == "glfw":
        return _diagnose_glfw(exc)
    return _diagnose_egl(exc, fix)


def _detail(exc: BaseException | None) -> str:
    detail = f"{type(exc).__name__}: {exc}" if exc is not None else "unknown cause"
    return " ".join(detail.split())


def _diagnose_osmesa(exc: BaseException | None) -> str:
    """MUJOCO_GL=osmesa: Mesa's off-screen library (being removed from Mesa)."""
    if not _loadable("libOSMesa.so.8") and not _loadable("libOSMesa.so"):
        return ("MUJOCO_GL=osmesa needs libOSMesa, which is not installed (apt-get install "
                "libosmesa6; Mesa is removing OSMesa: prefer MUJOCO_GL=egl, which runs "
                "on Mesa's software device without a GPU)")
    return f"cannot create an OSMesa context ({_detail(exc)}); unset MUJOCO_GL to use EGL"


def _diagnose_glfw(exc: BaseException | None) -> str:
    """MUJOCO_GL=glfw: a windowing library that needs an X or Wayland display."""
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        return ("MUJOCO_GL=glfw needs a display (DISPLAY is not set); unset MUJOCO_GL "
                "to render headless with EGL")
    return f"cannot create a GLFW context ({_detail(exc)}); unset MUJOCO_GL to use EGL"


def _diagnose_egl(exc: BaseException | None, fix: str) -> str:
    """MUJOCO_GL=egl (the default): libEGL, a vendor file, Mesa's software driver."""
    if not _loadable("libEGL.so.1"):
        return f"libEGL.so.1 is missing ({fix} libegl1)"
    if not _loadable("libOpenGL.so.0") and not _loadable("libGL.so.1"):
        return f"libOpenGL.so.0 / libGL.so.1 are missing ({fix} libopengl0 libgl1)"
    vendors = _egl_vendor_files()
    if not vendors:
        where = ("__EGL_VENDOR_LIBRARY_FILENAMES="
                 f"{os.environ['__EGL_VENDOR_LIBRARY_FILENAMES']!r} names no existing file"
                 if os.environ.get("__EGL_VENDOR_LIBRARY_FILENAMES")
                 else "no EGL vendor library is registered")
        return (f"{where}: need Mesa's libEGL_mesa.so.0 ({fix} libegl-mesa0) "
                f"or the NVIDIA driver")
    if any("mesa" in os.path.basename(v) for v in vendors) and not glob.glob(
            "/usr/lib/*/dri/swrast_dri.so") and not _has_nvidia(vendors):
        return f"Mesa's software driver swrast_dri.so is missing ({fix} libgl1-mesa-dri)"
    return f"cannot create an EGL context ({_detail(exc)}); check the EGL driver ({fix} " \
           f"libegl1 libegl-mesa0 libgl1-mesa-dri)"


def _has_nvidia(vendors) -> bool:
    return any("nvidia" in os.path.basename(v) for v in vendors)


@contextlib.contextmanager
def _gl_disabled():
    """``MUJOCO_GL=disable`` while a module that reads it at import executes."""
    saved = os.environ.get("MUJOCO_GL")
    os.environ["MUJOCO_GL"] = "disable"
    try:
        yield
    finally:
        if saved is None:
            del os.environ["MUJOCO_GL"]
        else:
            os.environ["MUJOCO_GL"] = saved


def _mujoco_loaded(mujoco) -> None:
    sys.modules[mujoco.Renderer.__module__].gl_context.GLContext = _gl_context
    mujoco.GLContext = _gl_context


def _dm_control_render_loaded(module) -> None:
    module.Renderer = dm_control_context


def _gl_context(*args, **kwargs):
    return use_gl_backend()(*args, **kwargs)


def install() -> None:
    """Defer the GL backend of mujoco and of dm_control's renderer, whenever they are first
    imported: each executes with ``MUJOCO_GL=disable`` and then gets the stand-ins that
    call :func:`use_gl_backend` at the first render. A mujoco imported before twolink keeps
    the backend it chose."""
    if "mujoco" not in sys.modules:
        around_import("mujoco", _mujoco_loaded, _gl_disabled)
    if "dm_control._render" not in sys.modules:
        around_import("dm_control._render", _dm_control_render_loaded, _gl_disabled)
