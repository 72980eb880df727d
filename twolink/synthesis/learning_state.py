"""The state of an online learner that outlives a process: the learning curve's points
(:class:`Evaluation`), float64 arrays packed as base64 text (:func:`pack`,
:func:`unpack`), and the check of a checkpoint's resume state before a learner is built
from it (:func:`check_resume_state`); :mod:`twolink.synthesis.learning` writes and reads
them."""
from __future__ import annotations

import base64
import dataclasses
import math

import numpy as np

from twolink.sim.metrics import Score
from twolink.synthesis.learning_setup import LearnConfig
from twolink.validate import is_whole, real


@dataclasses.dataclass(frozen=True)
class Evaluation:
    """Greedy policy (14) of the current theta on the evaluation set, on MuJoCo: the
    shared :class:`twolink.sim.metrics.Score` of its runs and when it was taken."""

    steps: int                 # control steps learned so far (all arms)
    score: Score               # successes, n, Wilson interval, median settle (one plant)
    mean_return: float         # discounted return of (15), mean over the states
    seconds: float             # wall time of learning so far (evaluations excluded)

    @property
    def successes(self) -> int:
        return self.score.successes

    @property
    def n(self) -> int:
        return self.score.n

    @property
    def rate(self) -> float:
        return self.score.rate

    @property
    def median_settle(self) -> float:        # seconds; inf when half or more fail
        return self.score.median_settle

    def as_dict(self) -> dict:
        """``steps``, the keys of :meth:`Score.as_dict`, ``mean_return``, ``seconds``."""
        return {"steps": self.steps, **self.score.as_dict(), "mean_return": self.mean_return,
                "seconds": self.seconds}

    @classmethod
    def from_dict(cls, d: dict) -> Evaluation:
        """A curve point of :meth:`as_dict` or of an older checkpoint (no interval, no
        worst plant: :meth:`twolink.sim.metrics.Score.from_dict`)."""
        return cls(int(d["steps"]), Score.from_dict(d), float(d["mean_return"]),
                   float(d["seconds"]))


def check_resume_state(info: dict, config: LearnConfig) -> dict:
    """The checked resume state of a checkpoint's learning metadata ``info`` for a run of
    ``config``: the arms' states ``x`` (arms, 4) and episode clocks ``clock`` (arms,),
    ``iterations`` and ``learn_seconds`` (numbers, not text), the learning ``curve``
    (evaluations), plus the raw ``rng``, ``theta``, ``patched`` and ``kept`` entries.
    Anything missing, of the wrong type or size, negative or not finite is a one-line
    ValueError "malformed learning checkpoint (<field>: ...)"; so is a checkpoint
    already past ``config.steps``."""
    def bad(why: str) -> ValueError:
        return ValueError(f"malformed learning checkpoint ({why})")

    state = info.get("resume")
    if not isinstance(state, dict):
        raise bad("resume must be an object")
    for key in ("rng", "x", "clock"):
        if key not in state:
            raise bad(f"no {key}")
    if not isinstance(state["rng"], dict):
        raise bad("rng must be an object")
    arms = config.arms
    x = state["x"]
    if isinstance(x, str):
        x = unpack(x, (arms, 4), "x")
    else:
        try:
            x = np.asarray(x)
        except (TypeError, ValueError):
            raise bad("x must be base64 text or a list of numbers") from None
        if x.dtype.kind not in "iuf" or x.size != 4 * arms or not np.all(np.isfinite(x)):
            raise bad(f"x must hold {4 * arms} finite numbers (4 per arm), got "
                      f"{x.size} values of dtype {x.dtype}")
        x = x.astype(float).reshape(arms, 4)
    clock = np.asarray(state["clock"]) if isinstance(state["clock"], list) else None
    if clock is None or clock.dtype.kind not in "iu" or clock.shape != (arms,) \
            or np.any(clock < 0):
        raise bad(f"clock must be a list of {arms} non-negative whole numbers (one per arm)")
    iterations = info.get("iterations")
    if not is_whole(iterations) or iterations < 0:
        raise bad(f"iterations must be a non-negative whole number, got {iterations!r}")
    seconds = info.get("learn_seconds")
    try:
        seconds = real(seconds, "learn_seconds", 0)
    except ValueError as exc:
        raise bad(str(exc)) from None
    if not isinstance(info.get("curve"), list) or \
            not all(isinstance(e, dict) for e in info["curve"]):
        raise bad("curve must be a list of evaluations")
    try:
        curve = [Evaluation.from_dict(e) for e in info["curve"]]
    except (KeyError, TypeError, ValueError) as exc:
        raise bad(f"curve: {exc}") from None
    if iterations * arms > config.steps:
        raise ValueError(f"the checkpoint is at {iterations * arms} steps, beyond the "
                         f"{config.steps} asked for")
    return {**state, "x": x, "clock": clock.astype(np.int64), "iterations": int(iterations),
            "learn_seconds": float(seconds), "curve": curve}


def indices(values, size: int, what: str) -> np.ndarray:
    """``values`` as an int64 array of indices in [0, size), else the checkpoint error."""
    arr = np.asarray(values) if isinstance(values, list) else None
    if arr is None or (arr.size and arr.dtype.kind not in "iu") \
            or (arr.size and (arr.min() < 0 or arr.max() >= size)):
        raise ValueError(f"malformed learning checkpoint ({what})")
    return arr.astype(np.int64).reshape(-1)


def pack(a: np.ndarray) -> str:
    """float64 array as base64 text (exact, and half the size of decimal JSON)."""
    return base64.b64encode(np.ascontiguousarray(a, dtype="<f8").tobytes()).decode("ascii")


def unpack(text: str, shape: tuple, what: str = "theta") -> np.ndarray:
    """The float64 array of ``shape`` packed by :func:`_pack`, else a one-line ValueError
    naming ``what`` (wrong size, not base64, not finite)."""
    try:
        raw = base64.b64decode(text.encode("ascii"), validate=True)
    except (ValueError, AttributeError) as exc:
        raise ValueError(f"malformed learning checkpoint ({what}: {exc})") from None
    if len(raw) != 8 * math.prod(shape):
        raise ValueError(f"malformed learning checkpoint ({what} of {len(raw)} bytes, "
                         f"expected {8 * math.prod(shape)})")
    arr = np.frombuffer(raw, dtype="<f8").reshape(shape).astype(float)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"malformed learning checkpoint ({what} not finite)")
    return arr
