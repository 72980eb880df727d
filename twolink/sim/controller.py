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
"""
from __future__ import annotations

import numpy as np


class ControllerError(ValueError):
    """A controller broke the protocol (one line: which controller, what it did)."""


def controller_name(controller, default: str = "controller") -> str:
    """The label of ``controller``: its ``name``, else its function or class name."""
    name = getattr(controller, "name", None)
    if isinstance(name, str) and name:
        return name
    name = getattr(controller, "__name__", None) or type(controller).__name__
    return name if name not in ("function", "NoneType") else default


class Checked:
    """``controller`` behind the protocol's checks; calls, ``reset`` and ``meta`` pass
    through. Output: float64 torques of shape x.shape[:-1] + (links,)."""

    def __init__(self, controller, *, name: str | None = None, links: int = 2):
        if isinstance(controller, Checked):
            controller = controller.controller
        if not callable(controller):
            raise ControllerError(f"controller {controller!r:.60} is not callable: a "
                                  f"controller maps states (n, {2 * links}) to torques "
                                  f"(n, {links})")
        self.controller = controller
        self.name = name or controller_name(controller)
        self.links = int(links)

    def __getattr__(self, name):
        """Other attributes (a policy's ``kind``, ``agents``, ...) are the controller's."""
        if name == "controller":
            raise AttributeError(name)
        return getattr(self.controller, name)

    @property
    def meta(self) -> dict:
        meta = getattr(self.controller, "meta", None)
        return dict(meta) if isinstance(meta, dict) else {}

    def reset(self, n: int) -> None:
        reset = getattr(self.controller, "reset", None)
        if callable(reset):
            try:
                reset(n)
            except Exception as exc:
                raise ControllerError(f"controller {self.name}: reset({n}) raised "
                                      f"{type(exc).__name__}: {exc}") from None

    def __call__(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        want = x.shape[:-1] + (self.links,)
        try:
            u = self.controller(x)
        except ControllerError:
            raise
        except Exception as exc:
            hint = ""
            if x.ndim == 2 and x.shape[0] > 1:
                hint = (f" (a controller is called on a batch of states (n, {x.shape[-1]});"
                        f" wrap a function of one state with twolink.per_state)")
            raise ControllerError(f"controller {self.name} raised {type(exc).__name__}: "
                                  f"{exc}{hint}") from None
        try:
            u = np.asarray(u, dtype=float)
        except (TypeError, ValueError):
            raise ControllerError(f"controller {self.name} returned {type(u).__name__}, "
                                  f"not an array of torques of shape {want}") from None
        if u.shape != want:
            one = u.shape == (self.links,) and x.ndim == 2
            raise ControllerError(
                f"controller {self.name} returned torques of shape {u.shape} for states of "
                f"shape {x.shape}; it must return {want}"
                + ("; wrap a function of one state with twolink.per_state" if one else ""))
        if not np.all(np.isfinite(u)):
            raise ControllerError(f"controller {self.name} returned NaN or infinite torques")
        return u


def checked(controller, *, name: str | None = None, links: int = 2) -> Checked:
    """``controller`` held to the protocol (see :class:`Checked`)."""
    return Checked(controller, name=name, links=links)


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
