"""Fuzzy Q-function policies (14): a centralized one (16) or two cooperating agents (18).

A :class:`Policy` is an ordered list of :class:`Agent` objects. Each agent reads named
signals (state components, and the outputs of the agents before it) through its fuzzy
grid, and outputs the membership-weighted average of the per-bin greedy actions
argmax_u Q(m, u) (14); ties go to the first action. The decentralized policy runs
agent 2 first and hands its tau2 to agent 1, as in (18).

Policy files are ``.npz`` archives holding the Q-tables and a JSON header with the
provenance (parameters, bins, gamma, delta, iterations, model, package version); they are
written atomically and refused with a clear error when they are not twolink policies.
"""
from __future__ import annotations

import dataclasses
import json
import os
import zipfile
from pathlib import Path

import numpy as np

from twolink.artifacts import atomic_path
from twolink.fuzzy import Grid
from twolink.parameters import STATE_NAMES
from twolink.registry import SHIPPED

FORMAT = "twolink-policy"
FORMAT_VERSION = 1


class PolicyFileError(ValueError):
    """A file that is not a valid twolink policy."""


@dataclasses.dataclass
class Agent:
    """One fuzzy Q-table controller.

    ``grid`` axes are named after the signals the agent reads; ``actions`` has shape
    (N_U, len(outputs)); ``q`` has shape (grid.size, N_U).
    """

    name: str
    grid: Grid
    actions: np.ndarray
    q: np.ndarray
    outputs: tuple
    info: dict = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        self.actions = np.asarray(self.actions, dtype=float)
        self.q = np.asarray(self.q, dtype=float)
        self.outputs = tuple(self.outputs)
        if self.actions.ndim != 2 or self.actions.shape[1] != len(self.outputs):
            raise ValueError(f"agent {self.name}: actions must have shape (N_U, "
                             f"{len(self.outputs)}), got {self.actions.shape}")
        if self.q.shape != (self.grid.size, len(self.actions)):
            raise ValueError(f"agent {self.name}: Q must have shape "
                             f"({self.grid.size}, {len(self.actions)}), got {self.q.shape}")
        if not np.all(np.isfinite(self.q)):
            raise ValueError(f"agent {self.name}: Q contains NaN or infinite values")
        self._greedy = self.actions[np.argmax(self.q, axis=1)]

    @property
    def inputs(self) -> tuple:
        return self.grid.names

    @property
    def greedy_actions(self) -> np.ndarray:
        """argmax_u Q(m, u) for every bin m, shape (N_X, len(outputs))."""
        return self._greedy

    def act(self, points: np.ndarray) -> np.ndarray:
        """Policy (14) for points of shape (..., d): shape (..., len(outputs))."""
        return self.grid.interpolate(self._greedy, points)

    def q_values(self, points: np.ndarray) -> np.ndarray:
        """Interpolated Q-values (12) of points (..., d): shape (..., N_U)."""
        return self.grid.interpolate(self.q, points)


class Policy:
    """A state-feedback policy tau = h(x) made of one or more agents, evaluated in order."""

    def __init__(self, kind: str, agents, meta: dict | None = None):
        self.kind = kind
        self.agents = list(agents)
        self.meta = dict(meta or {})
        known = set(STATE_NAMES)
        for agent in self.agents:
            missing = [n for n in agent.inputs if n not in known]
            if missing:
                raise ValueError(f"agent {agent.name} reads {missing}, which no earlier "
                                 f"agent or state component provides")
            known.update(agent.outputs)
        if not {"tau1", "tau2"} <= known:
            raise ValueError(f"policy {kind}: its agents must output tau1 and tau2")

    def __repr__(self):
        sizes = ", ".join(f"{a.name}: {a.q.size}" for a in self.agents)
        return f"Policy({self.kind!r}, Q sizes {{{sizes}}})"

    def __call__(self, x) -> np.ndarray:
        """Torques [tau1, tau2] for states x of shape (..., 4)."""
        x = np.asarray(x, dtype=float)
        if x.ndim == 0 or x.shape[-1] != 4:
            raise ValueError(f"policy input must have shape (..., 4), got {x.shape}")
        if not np.all(np.isfinite(x)):
            raise ValueError("policy input contains NaN or infinite values")
        signals = {name: x[..., k] for k, name in enumerate(STATE_NAMES)}
        for agent in self.agents:
            points = np.stack([signals[n] for n in agent.inputs], -1)
            out = agent.act(points)
            for k, name in enumerate(agent.outputs):
                signals[name] = out[..., k]
        return np.stack([signals["tau1"], signals["tau2"]], -1)

    @property
    def q_sizes(self) -> dict:
        return {a.name: int(a.q.size) for a in self.agents}

    # ----------------------------------------------------------------- files
    def header(self) -> dict:
        return {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "kind": self.kind,
            "meta": self.meta,
            "agents": [{"name": a.name, "grid": a.grid.as_dict(), "outputs": list(a.outputs),
                        "actions": a.actions.tolist(), "info": a.info} for a in self.agents],
        }

    def save(self, path: os.PathLike) -> Path:
        """Write the policy atomically (a temporary file, then a rename)."""
        path = Path(path)
        arrays = {f"q_{a.name}": a.q for a in self.agents}
        header = np.array(json.dumps(self.header(), sort_keys=True))
        with atomic_path(path) as tmp:
            with open(tmp, "wb") as fh:
                np.savez_compressed(fh, header=header, **arrays)
        return path

    @classmethod
    def load(cls, path: os.PathLike) -> "Policy":
        """Load a policy file, refusing anything that is not a well-formed twolink policy."""
        path = Path(path)
        if not path.is_file():
            raise PolicyFileError(f"policy file {path} does not exist")
        try:
            with np.load(path, allow_pickle=False) as npz:
                files = {k: npz[k] for k in npz.files}
        except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
            raise PolicyFileError(f"{path} is not a twolink policy file (not a readable "
                                  f".npz archive: {exc})") from None
        try:
            header = json.loads(str(files["header"]))
        except (KeyError, json.JSONDecodeError):
            raise PolicyFileError(f"{path} is not a twolink policy file (no policy header)") \
                from None
        if not isinstance(header, dict) or header.get("format") != FORMAT:
            raise PolicyFileError(f"{path} is not a twolink policy file "
                                  f"(format {header.get('format') if isinstance(header, dict) else None!r})")
        if header.get("format_version") != FORMAT_VERSION:
            raise PolicyFileError(f"{path}: unsupported policy format version "
                                  f"{header.get('format_version')!r} (expected {FORMAT_VERSION})")
        agents = []
        try:
            for entry in header["agents"]:
                key = f"q_{entry['name']}"
                if key not in files:
                    raise PolicyFileError(f"{path}: Q-table of agent {entry['name']} is missing")
                agents.append(Agent(entry["name"], Grid.from_dict(entry["grid"]),
                                    np.asarray(entry["actions"], dtype=float), files[key],
                                    tuple(entry["outputs"]), entry.get("info", {})))
            return cls(header["kind"], agents, header.get("meta", {}))
        except PolicyFileError:
            raise
        except (KeyError, TypeError, ValueError) as exc:
            raise PolicyFileError(f"{path}: malformed twolink policy ({exc})") from None


def shipped_policies() -> list[str]:
    """Names of the shipped policies (:data:`twolink.registry.SHIPPED`), in report order."""
    return list(SHIPPED)


def load_policy(name_or_path: str | os.PathLike) -> Policy:
    """A shipped policy by name (e.g. ``centralized``) or a policy file by path."""
    text = str(name_or_path)
    if os.sep not in text and not text.endswith(".npz"):
        if text in SHIPPED:
            return Policy.load(SHIPPED[text].file)
        raise PolicyFileError(f"unknown policy {text!r}; shipped policies: "
                              f"{', '.join(SHIPPED)} (or give a .npz path)")
    return Policy.load(Path(text))
