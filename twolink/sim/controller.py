"""The controller protocol: what every controller the testbed runs looks like.

A *controller* maps a batch of states x (n, 2N) (angles wrapped to [-pi, pi), speeds in
rad/s, the order of :func:`twolink.arm.parameters.state_names`) to torques (n, N). It
may also have:

* ``reset(n)``: called before every rollout of n rows, for a controller with state
  (a filter, an integrator, the last command);
* ``meta``: a dict; ``meta["model"]`` (``"full"``, ``"simplified"``) and
  ``meta["parameters"]`` name the model a compensator predicts with
  (:mod:`twolink.sim.estimation`), as a policy file's provenance does;
* ``name``: how tables label it.

Shipped fuzzy policies (:class:`twolink.policy.fuzzy_policy.Policy`), the classical
baselines and a plain function ``def f(x): return -K @ x.T`` all satisfy it.
:func:`checked` wraps any of them so that a wrong shape, a NaN or an exception ends in one
:class:`ControllerError` line naming the controller and the problem; :func:`per_state`
turns a function of one state (2N,) -> (N,) into a controller (a Python loop over the
rows: fine for trying an idea, slow for a leaderboard).

A checked controller cannot reach the caller's data: each call gets a read-only copy of
the states (a write raises numpy's error, reported as a ControllerError) and returns a new
float64 array. Torques must hold real numbers (ints or floats; not bools, complex numbers,
strings or objects). While it runs, ``print`` goes to stderr (so a command's ``--json``
output stays clean); ``sys.exit``, a ``KeyboardInterrupt`` it raises itself (not a
Ctrl-C) and any other exception end in a ControllerError; with ``timeout`` a call that
runs longer ends in one too (:class:`Checked`).
"""
from __future__ import annotations

import contextlib
import math
import signal
import sys
import threading

import numpy as np

#: Bounds of a per-call time limit, in seconds: below a millisecond the interval timer
#: is not to be trusted, above an hour it limits nothing.
MIN_TIMEOUT, MAX_TIMEOUT = 0.001, 3600.0


class ControllerError(ValueError):
    """A controller broke the protocol (one line: which controller, what it did)."""


def check_timeout(timeout, what: str = "timeout") -> float | None:
    """``timeout`` as a float number of seconds from :data:`MIN_TIMEOUT` to
    :data:`MAX_TIMEOUT`, None for none; a one-line ValueError naming ``what`` otherwise."""
    if timeout is None:
        return None
    ok = isinstance(timeout, (int, float, np.integer, np.floating)) \
        and not isinstance(timeout, bool) and math.isfinite(float(timeout)) \
        and MIN_TIMEOUT <= float(timeout) <= MAX_TIMEOUT
    if not ok:
        raise ValueError(f"{what} must be a number of seconds from {MIN_TIMEOUT:g} to "
                         f"{MAX_TIMEOUT:g}, got {timeout!r}")
    return float(timeout)


class _CallTimeout(BaseException):
    """Raised by SIGALRM inside a controller call that outlived its limit (a
    BaseException, so that a controller's ``except Exception`` does not swallow it)."""


class _CallState:
    """What the guarded controller call under way on the main thread has seen."""

    guarded = False     # an outermost guard holds SIGINT
    timing = False      # a guard's alarm is armed
    sigint = False      # a real SIGINT (Ctrl-C) arrived during the call
    pending = False     # ... while this module's own code ran: delivered on the way out
    expired = False     # the alarm went off


_STATE = _CallState()


def _ours(frame) -> bool:
    """Whether ``frame`` runs this module's code (the guard, not the controller)."""
    return frame is not None and frame.f_globals.get("__name__") == __name__


class _Calling:
    """The context of one controller call (or ``reset``): ``print`` goes to stderr; on
    the main thread, a SIGINT arriving during the call is recorded and handled as before
    (Ctrl-C raises KeyboardInterrupt), and with ``timeout`` SIGALRM raises
    :class:`_CallTimeout` after ``timeout`` seconds, again every ``timeout`` seconds while
    the call goes on. A signal that lands in the guard's own code rather than the
    controller's is raised on the way out, after the handlers and the timer are restored;
    so is one the controller swallowed."""

    def __init__(self, timeout: float | None):
        self.timeout = timeout
        self.hold_int = self.arm = False

    def __enter__(self):
        self.redirect = contextlib.redirect_stdout(sys.stderr)
        self.redirect.__enter__()
        if threading.current_thread() is not threading.main_thread():
            return self
        self.hold_int = not _STATE.guarded
        if self.hold_int:
            _STATE.guarded, _STATE.sigint, _STATE.pending = True, False, False
            self.previous_int = signal.signal(signal.SIGINT, self._on_sigint)
        self.arm = (self.timeout is not None and not _STATE.timing
                    and hasattr(signal, "setitimer"))
        if self.arm:
            _STATE.timing, _STATE.expired = True, False
            self.previous_alarm = signal.signal(signal.SIGALRM, _on_alarm)
            self.previous_timer = signal.setitimer(signal.ITIMER_REAL, self.timeout,
                                                   self.timeout)
        return self

    def _on_sigint(self, signum, frame):
        if self.previous_int == signal.SIG_IGN:
            return
        _STATE.sigint = True
        if _ours(frame):
            _STATE.pending = True
        else:
            self._deliver_sigint(signum, frame)

    def _deliver_sigint(self, signum=signal.SIGINT, frame=None):
        """Ctrl-C as the handler in force before would have taken it (it raises)."""
        if callable(self.previous_int):
            self.previous_int(signum, frame)
        raise KeyboardInterrupt

    def __exit__(self, kind, exc, tb):
        try:
            if self.arm:
                _STATE.timing = False
                signal.setitimer(signal.ITIMER_REAL, 0)
                signal.signal(signal.SIGALRM, self.previous_alarm)
                delay, interval = self.previous_timer
                if delay > 0:            # someone else's timer: it goes on
                    signal.setitimer(signal.ITIMER_REAL, delay, interval)
            if self.hold_int:
                _STATE.guarded = False
                signal.signal(signal.SIGINT, self.previous_int)
        finally:
            self.redirect.__exit__(kind, exc, tb)
        interrupted = kind is not None and issubclass(kind, KeyboardInterrupt)
        if self.hold_int and _STATE.sigint and (_STATE.pending or not interrupted):
            self._deliver_sigint()       # the user's Ctrl-C, deferred or swallowed
        if kind is None and self.arm and _STATE.expired:
            raise _CallTimeout
        return False


def _on_alarm(signum, frame):
    if _STATE.timing:
        _STATE.expired = True
        if not _ours(frame):
            raise _CallTimeout


def _one_line(text) -> str:
    return " ".join(str(text).split())


def controller_name(controller, default: str = "controller") -> str:
    """The label of ``controller``: its ``name``, else its function or class name."""
    name = getattr(controller, "name", None)
    if isinstance(name, str) and name:
        return name
    name = getattr(controller, "__name__", None) or type(controller).__name__
    return name if name not in ("function", "NoneType") else default


class Checked:
    """``controller`` behind the protocol's checks; calls, ``reset`` and ``meta`` pass
    through. Output: a new float64 array of torques of shape x.shape[:-1] + (links,).

    Each call hands the controller a read-only float64 copy of the states and runs it
    with ``print`` going to stderr. Everything it can do wrong ends in one
    :class:`ControllerError` line naming it: raising (an attempt to write into the
    states included), calling ``sys.exit``, raising ``KeyboardInterrupt`` itself (a
    Ctrl-C of the user stays a KeyboardInterrupt), returning anything but real numbers
    (ints or floats: not bools, complex numbers, strings or objects) of the right shape,
    NaN or infinite torques, and, with ``timeout`` (seconds, :func:`check_timeout`),
    taking longer than that on one call or ``reset``. The limit is a SIGALRM timer, so it
    applies to calls made on the main thread only (a call elsewhere runs unlimited), and
    a call stuck inside C code ends when that code hands back to Python. Wrapping a
    Checked keeps its ``timeout`` unless another is given."""

    def __init__(self, controller, *, name: str | None = None, links: int = 2,
                 timeout: float | None = None):
        if isinstance(controller, Checked):
            if timeout is None:
                timeout = controller.timeout
            controller = controller.controller
        if not callable(controller):
            raise ControllerError(f"controller {controller!r:.60} is not callable: a "
                                  f"controller maps states (n, {2 * links}) to torques "
                                  f"(n, {links})")
        self.controller = controller
        self.name = name or controller_name(controller)
        self.links = int(links)
        self.timeout = check_timeout(timeout)

    def __getattr__(self, name):
        """Other attributes (a policy's ``kind``, ``agents``, ...) are the controller's."""
        if name in ("controller", "timeout"):
            raise AttributeError(name)
        return getattr(self.controller, name)

    @property
    def meta(self) -> dict:
        meta = getattr(self.controller, "meta", None)
        return dict(meta) if isinstance(meta, dict) else {}

    def _guarded(self, call, arg, what: str, hint: str = ""):
        """``call(arg)`` in a :class:`_Calling` context; whatever it raises (but a real
        Ctrl-C or SIGTERM, or a ControllerError of a controller it wraps) becomes one
        ControllerError line naming the controller, ``what`` saying which call it was."""
        try:
            with _Calling(self.timeout):
                return call(arg)
        except ControllerError:
            raise
        except _CallTimeout:
            raise ControllerError(f"controller {self.name} took longer than "
                                  f"{self.timeout:g} s on one call") from None
        except SystemExit as exc:
            raise ControllerError(f"controller {self.name} called sys.exit({exc.code!r})"
                                  f"{what}; a controller must return torques, not end "
                                  f"the program") from None
        except KeyboardInterrupt as exc:
            if type(exc) is not KeyboardInterrupt or _STATE.sigint:
                raise                    # Ctrl-C (or SIGTERM) of the user: as ever
            raise ControllerError(f"controller {self.name} raised KeyboardInterrupt{what} "
                                  f"(no Ctrl-C was pressed)") from None
        except BaseException as exc:     # noqa: B036 (every other exception is the controller's)
            note = ""
            if isinstance(exc, ValueError) and "read-only" in str(exc):
                note = " (the states a controller gets are read-only: copy them to change them)"
                hint = ""
            raise ControllerError(f"controller {self.name}{what} raised "
                                  f"{type(exc).__name__}: {_one_line(exc)}{note}{hint}"
                                  ) from None

    def reset(self, n: int) -> None:
        reset = getattr(self.controller, "reset", None)
        if callable(reset):
            self._guarded(reset, n, f" in reset({n})")

    def __call__(self, x) -> np.ndarray:
        x = np.array(x, dtype=float)         # the controller's own copy, read-only
        x.setflags(write=False)
        want = x.shape[:-1] + (self.links,)
        hint = ""
        if x.ndim == 2 and x.shape[0] > 1:
            hint = (f" (a controller is called on a batch of states (n, {x.shape[-1]});"
                    f" wrap a function of one state with twolink.per_state)")
        u = self._guarded(self.controller, x, "", hint)
        return self._torques(u, x.shape, want)

    def _torques(self, u, shape: tuple, want: tuple) -> np.ndarray:
        """``u`` as a new float64 array of shape ``want``, or a ControllerError line."""
        try:
            arr = np.asarray(u)
        except Exception:
            arr = None
        if arr is None or arr.dtype.kind not in "iuf":
            what = type(u).__name__
            if arr is not None and isinstance(u, (np.ndarray, list, tuple)):
                what += f" of dtype {arr.dtype}"
            raise ControllerError(f"controller {self.name} returned {what}, not an array of "
                                  f"real torques of shape {want}")
        if arr.shape != want:
            one = arr.shape == (self.links,) and len(shape) == 2
            raise ControllerError(
                f"controller {self.name} returned torques of shape {arr.shape} for states of "
                f"shape {shape}; it must return {want}"
                + ("; wrap a function of one state with twolink.per_state" if one else ""))
        u = np.array(arr, dtype=float)       # a new array: the controller keeps no handle
        if not np.all(np.isfinite(u)):
            raise ControllerError(f"controller {self.name} returned NaN or infinite torques")
        return u


def checked(controller, *, name: str | None = None, links: int = 2,
            timeout: float | None = None) -> Checked:
    """``controller`` held to the protocol (see :class:`Checked`), each call limited to
    ``timeout`` seconds when given."""
    return Checked(controller, name=name, links=links, timeout=timeout)


class PerState:
    """A function of one state (2N,) -> (N,) as a batched controller (loops over rows)."""

    def __init__(self, function, *, name: str | None = None, meta: dict | None = None):
        if not callable(function):
            raise ControllerError(f"per_state needs a function, got {type(function).__name__}")
        self.function = function
        self.name = name or controller_name(function)
        if meta is not None:
            self.meta = dict(meta)

    def __call__(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        rows = x.reshape(-1, x.shape[-1])
        out = np.array([np.asarray(self.function(r), dtype=float) for r in rows])
        return out.reshape(x.shape[:-1] + out.shape[1:])


def per_state(function, *, name: str | None = None, meta: dict | None = None) -> PerState:
    """Make a controller of ``function(state) -> torques`` (see :class:`PerState`)."""
    return PerState(function, name=name, meta=meta)


def reset_controller(controller, rows: int) -> None:
    """Call ``reset(rows)`` of ``controller`` before a rollout: its own, or that of the
    controller it wraps (a delay line's ``policy``, a checked ``controller``), the first
    one found going inwards."""
    seen = set()
    obj = controller
    while obj is not None and id(obj) not in seen:
        seen.add(id(obj))
        reset = getattr(obj, "reset", None)
        if callable(reset):
            reset(rows)
            return
        obj = getattr(obj, "policy", None) or getattr(obj, "controller", None)
