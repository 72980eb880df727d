"""Fuzzy Q-function policies (14): a centralized one (16) or two cooperating agents (18).

A :class:`Policy` is an ordered list of :class:`Agent` objects. Each agent reads named
signals (state components, and the outputs of the agents before it) through its fuzzy
grid, and outputs the membership-weighted average of the per-bin greedy actions
argmax_u Q(m, u) (14); actions whose Q lies within :data:`TIE_TOLERANCE` of the best
are tied and the first of them wins (docs/conventions.md), so round-off never decides an action. The
decentralized policy runs agent 2 first and hands its tau2 to agent 1, as in (18).

A policy may read its states through dead zones (:mod:`twolink.policy.readout`,
``meta["readout"]``) before its agents see them.

A policy is for an arm of N = :attr:`Policy.links` links (``meta["links"]``, 2 when
absent): it reads states x = [theta_1..theta_N, dtheta_1..dtheta_N] and its agents
together output tau1..tauN. Files of two-link policies carry no ``links``.

Policy files are ``.npz`` archives holding the Q-tables and a JSON header with the
provenance (parameters, bins, gamma, delta, iterations, model, package version) and a
sha256 of the content (header, actions, grids and Q-tables). They are written atomically.
Loading checks member sizes before decompressing anything, the data types (real, finite
numbers only) and the sha256, and refuses anything else with one line naming the file.
The hash detects edits and corruption; it is not a signature.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import zipfile
from pathlib import Path

import numpy as np

from twolink.arm.parameters import check_links, state_names
from twolink.artifacts import atomic_path
from twolink.fqi.fuzzy import Grid
from twolink.policy.readout import Readout
from twolink.policy.registry import SHIPPED
from twolink.validate import real, real_array

FORMAT = "twolink-policy"
#: Version 2 added the content sha256 and the per-agent tie tolerance.
FORMAT_VERSION = 2

#: Two Q-values closer than this are tied in policy (14); the first tied action wins.
#: Q is in units of the reward (15)/(17), which lies in [-0.5, 0], so |Q| <= 0.5/(1-gamma)
#: = 25. Round-off in the Q of the shipped policies is below 1.5e-14 (the 1e-16 relative
#: precision of a float, times |Q| <= 25, summed over some 200 sweeps, stays under 1e-11),
#: while the smallest genuine difference between the best two actions of a bin is 1.6e-5.
#: 1e-9 sits two decades above the round-off bound and four below that smallest genuine
#: gap; it is 1e-7 of the stopping threshold delta = 0.01 and 4e-11 of the Q scale 25.
#: It absorbs round-off only: it is not a convergence margin (Alg. 1 stops with Q up to
#: gamma*delta/(1-gamma) = 0.49 from its fixed point, which no tolerance could absorb
#: without changing the policy). ``docs/studies/tie_sensitivity.py`` measures what it moves.
TIE_TOLERANCE = 1e-9

#: The largest header a policy file may hold (bytes, uncompressed).
_MAX_HEADER_BYTES = 1 << 20
#: The largest Q-table a policy file may hold (bytes, uncompressed): 64 MiB, some 130 times
#: the centralized table of the paper.
MAX_Q_BYTES = 64 << 20
#: Most inputs an agent may read: a state weighs up to 2**d bins of a d-input grid (12: the
#: centralized policy of a six-link arm).
MAX_AXES = 12
#: Room for the .npy header in front of a Q-table's data.
_NPY_HEADER_BYTES = 4096


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
    tie_tolerance: float = TIE_TOLERANCE

    def __post_init__(self):
        self.actions = real_array(self.actions, f"agent {self.name}: actions")
        self.q = real_array(self.q, f"agent {self.name}: Q")
        self.outputs = tuple(self.outputs)
        self.tie_tolerance = real(self.tie_tolerance, f"agent {self.name}: tie tolerance",
                                  0, 1, open_high=True, numpy=False)
        if self.actions.ndim != 2 or self.actions.shape[1] != len(self.outputs):
            raise ValueError(f"agent {self.name}: actions must have shape (N_U, "
                             f"{len(self.outputs)}), got {self.actions.shape}")
        if self.q.shape != (self.grid.size, len(self.actions)):
            raise ValueError(f"agent {self.name}: Q must have shape "
                             f"({self.grid.size}, {len(self.actions)}), got {self.q.shape}")
        self._greedy = self.actions[greedy_indices(self.q, self.tie_tolerance)]

    @property
    def inputs(self) -> tuple:
        return self.grid.names

    @property
    def greedy_actions(self) -> np.ndarray:
        """argmax_u Q(m, u) for every bin m, ties within the tolerance to the first action;
        shape (N_X, len(outputs))."""
        return self._greedy

    def act(self, points: np.ndarray) -> np.ndarray:
        """Policy (14) for points of shape (..., d): shape (..., len(outputs))."""
        return self.grid.interpolate(self._greedy, points)

    def q_values(self, points: np.ndarray) -> np.ndarray:
        """Interpolated Q-values (12) of points (..., d): shape (..., N_U)."""
        return self.grid.interpolate(self.q, points)


def greedy_indices(q: np.ndarray, tolerance: float = TIE_TOLERANCE) -> np.ndarray:
    """Index of the greedy action of every row of Q (N_X, N_U): the first action whose Q
    lies within ``tolerance`` of the row's best (``tolerance=0``: plain ``argmax``)."""
    q = np.asarray(q, dtype=float)
    return np.argmax(q >= q.max(axis=1, keepdims=True) - tolerance, axis=1)


def _content_hash(header: dict, q_tables: dict) -> str:
    """sha256 of the header (without its hash, canonical JSON) and the Q-tables (float64,
    little-endian, C order, in the header's agent order)."""
    body = {k: v for k, v in header.items() if k != "sha256"}
    h = hashlib.sha256(json.dumps(body, sort_keys=True, allow_nan=False).encode())
    for entry in header["agents"]:
        q = np.ascontiguousarray(q_tables[entry["name"]], dtype="<f8")
        h.update(entry["name"].encode() + b"\0" + repr(q.shape).encode() + b"\0")
        h.update(q.tobytes())
    return h.hexdigest()


def same_tables(a: "Policy", b: "Policy") -> bool:
    """Whether policies ``a`` and ``b`` act alike bit for bit: the same kind, links and
    readout, and agent by agent the same name, grid, actions, outputs, tie tolerance and
    Q-table (float64 bits). Their ``meta`` and ``info`` (timings, provenance) do not count."""
    if (a.kind, a.links, a.readout.as_dict(), len(a.agents)) != \
            (b.kind, b.links, b.readout.as_dict(), len(b.agents)):
        return False
    return all(x.name == y.name and x.grid.as_dict() == y.grid.as_dict()
               and tuple(x.outputs) == tuple(y.outputs) and x.tie_tolerance == y.tie_tolerance
               and np.array_equal(x.actions, y.actions) and x.q.shape == y.q.shape
               and np.ascontiguousarray(x.q, dtype="<f8").tobytes()
               == np.ascontiguousarray(y.q, dtype="<f8").tobytes()
               for x, y in zip(a.agents, b.agents))


def _torque_names(links: int) -> tuple:
    return tuple(f"tau{i}" for i in range(1, links + 1))


class Policy:
    """A state-feedback policy tau = h(x) made of one or more agents, evaluated in order,
    for an arm of ``meta["links"]`` links (2 when absent)."""

    def __init__(self, kind: str, agents, meta: dict | None = None):
        self.kind = kind
        self.agents = list(agents)
        self.meta = dict(meta or {})
        self._links = check_links(self.meta.get("links", 2))
        self._state_names = state_names(self._links)
        self._outputs = _torque_names(self._links)
        self._readout = Readout.from_dict(self.meta["readout"]) if "readout" in self.meta \
            else Readout()
        known = set(self._state_names)
        for agent in self.agents:
            missing = [n for n in agent.inputs if n not in known]
            if missing:
                raise ValueError(f"agent {agent.name} reads {missing}, which no earlier "
                                 f"agent or state component provides")
            known.update(agent.outputs)
        if not set(self._outputs) <= known:
            names = ", ".join(self._outputs[:-1]) + " and " + self._outputs[-1]
            raise ValueError(f"policy {kind}: its agents must output {names}")

    @property
    def links(self) -> int:
        """N, the number of links of the arm this policy is for."""
        return self._links

    @property
    def readout(self) -> Readout:
        """The dead zones on the readings (``meta["readout"]``; none when absent)."""
        return self._readout

    def __repr__(self):
        sizes = ", ".join(f"{a.name}: {a.q.size}" for a in self.agents)
        return f"Policy({self.kind!r}, Q sizes {{{sizes}}})"

    def __call__(self, x) -> np.ndarray:
        """Torques [tau1..tauN] (..., N) for states x of shape (..., 2N)."""
        x = np.asarray(x, dtype=float)
        width = 2 * self._links
        if x.ndim == 0 or x.shape[-1] != width:
            arm = "" if self._links == 2 else f" (a {self._links}-link policy)"
            raise ValueError(f"policy input must have shape (..., {width}), got {x.shape}{arm}")
        if not np.all(np.isfinite(x)):
            raise ValueError("policy input contains NaN or infinite values")
        gain = self._readout.gain(x, self._links)
        x = self._readout.apply(x, self._links)
        signals = {name: x[..., k] for k, name in enumerate(self._state_names)}
        for agent in self.agents:
            points = np.stack([signals[n] for n in agent.inputs], -1)
            out = agent.act(points)
            far = self._readout.far(points, agent.inputs)
            if far is not None and np.any(far):
                q = agent.q_values(points[far])
                out[far] = agent.actions[greedy_indices(q, agent.tie_tolerance)]
            for k, name in enumerate(agent.outputs):
                signals[name] = out[..., k]
        tau = np.stack([signals[name] for name in self._outputs], -1)
        return tau if gain is None else tau * gain

    def with_readout(self, readout: Readout, *, table: str | None = None) -> "Policy":
        """This policy's agents (the same Q-tables, not copied) read through ``readout``
        instead of its own; ``meta["table"]`` names where the tables come from when
        given. A read-out is data over a table: it never changes the tables."""
        if not isinstance(readout, Readout):
            raise TypeError(f"readout must be a twolink.policy.readout.Readout, got "
                            f"{type(readout).__name__}")
        meta = {k: v for k, v in self.meta.items() if k != "readout"}
        if readout.active:
            meta["readout"] = readout.as_dict()
        if table is not None:
            meta["table"] = str(table)
        return Policy(self.kind, self.agents, meta)

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
                        "actions": a.actions.tolist(), "q_shape": list(a.q.shape),
                        "tie_tolerance": a.tie_tolerance, "info": a.info}
                       for a in self.agents],
        }

    def save(self, path: os.PathLike) -> Path:
        """Write the policy atomically (a temporary file, then a rename), with its sha256."""
        path = Path(path)
        for a in self.agents:          # what load() would refuse is never written
            if a.q.nbytes > MAX_Q_BYTES:
                raise ValueError(f"agent {a.name}: a Q-table of {a.q.nbytes} bytes is larger "
                                 f"than the {MAX_Q_BYTES} bytes a policy file may hold")
        header = self.header()
        header["sha256"] = _content_hash(header, {a.name: a.q for a in self.agents})
        arrays = {f"q_{a.name}": np.ascontiguousarray(a.q, dtype="<f8") for a in self.agents}
        text = np.array(json.dumps(header, sort_keys=True, allow_nan=False))
        with atomic_path(path) as tmp:
            with open(tmp, "wb") as fh:
                np.savez_compressed(fh, header=text, **arrays)
        return path

    @classmethod
    def load(cls, path: os.PathLike) -> "Policy":
        """Load a policy file, refusing anything that is not a well-formed twolink policy.

        Sizes are checked against the header before any Q-table is decompressed; the data
        must be real and finite, and the content must match the file's sha256.
        """
        path = Path(path)
        if not path.is_file():
            what = ("is a directory" if path.is_dir() else "is not a regular file"
                    if path.exists() else "does not exist")
            raise PolicyFileError(f"policy file {path} {what}")
        try:
            with zipfile.ZipFile(path) as zf:
                header, q_tables = _read_policy_archive(zf, path)
        except PolicyFileError:
            raise
        except (OSError, ValueError, zipfile.BadZipFile, EOFError, RuntimeError) as exc:
            raise PolicyFileError(f"{path} is not a twolink policy file (not a readable "
                                  f".npz archive: {exc})") from None
        try:
            digest = _content_hash(header, q_tables)
        except (TypeError, ValueError) as exc:     # e.g. NaN or Infinity in the header
            raise PolicyFileError(f"{path}: malformed twolink policy ({exc})") from None
        if digest != header.get("sha256"):
            raise PolicyFileError(f"{path}: content does not match the file's sha256 (the "
                                  f"header or a Q-table was edited or corrupted)")
        try:
            agents = [Agent(e["name"], Grid.from_dict(e["grid"]),
                            real_array(e["actions"], f"agent {e['name']}: actions"),
                            q_tables[e["name"]], tuple(e["outputs"]), e.get("info", {}),
                            e["tie_tolerance"])
                      for e in header["agents"]]
            return cls(header["kind"], agents, header.get("meta", {}))
        except (KeyError, TypeError, ValueError) as exc:
            raise PolicyFileError(f"{path}: malformed twolink policy ({exc})") from None


def _member_size(zf: zipfile.ZipFile, name: str, limit: int, path: Path, what: str,
                 needs: str = "a policy file allows") -> None:
    """Refuse a member whose declared uncompressed size exceeds ``limit`` (reading never
    goes past the declared size, so this check holds before anything is decompressed)."""
    size = zf.getinfo(name).file_size
    if size > limit:
        raise PolicyFileError(f"{path}: {what} ({name}) holds {size} bytes uncompressed, more "
                              f"than the {limit} {needs}; refused before decompressing")


def _read_member(zf: zipfile.ZipFile, name: str, max_bytes: int, path: Path) -> np.ndarray:
    """The array of the .npy member ``name``, its own header's shape and dtype checked
    against ``max_bytes`` before anything is allocated."""
    fmt = np.lib.format
    with zf.open(name) as fh:
        try:
            version = fmt.read_magic(fh)
            read_header = (fmt.read_array_header_1_0 if version == (1, 0)
                           else fmt.read_array_header_2_0)
            shape, fortran, dtype = read_header(fh)
        except ValueError as exc:
            raise PolicyFileError(f"{path}: member {name} is not a .npy array ({exc})") \
                from None
        if dtype.hasobject:
            raise PolicyFileError(f"{path}: member {name} holds Python objects")
        nbytes = math.prod(shape) * dtype.itemsize
        if nbytes > max_bytes:
            raise PolicyFileError(f"{path}: member {name} declares an array of shape {shape} "
                                  f"({nbytes:,} bytes), more than the {max_bytes:,} it may "
                                  f"hold")
        data = fh.read(nbytes)
    if len(data) != nbytes:
        raise PolicyFileError(f"{path}: member {name} is truncated")
    return np.frombuffer(data, dtype).reshape(shape, order="F" if fortran else "C").copy()


def _read_policy_archive(zf: zipfile.ZipFile, path: Path) -> tuple[dict, dict]:
    """The header and the Q-tables of a policy archive, each member's size checked first."""
    names = set(zf.namelist())
    if "header.npy" not in names:
        raise PolicyFileError(f"{path} is not a twolink policy file (no policy header)")
    _member_size(zf, "header.npy", _MAX_HEADER_BYTES, path, "the header")
    raw = _read_member(zf, "header.npy", _MAX_HEADER_BYTES, path)
    if raw.dtype.kind != "U" or raw.ndim != 0:
        raise PolicyFileError(f"{path} is not a twolink policy file (no policy header)")
    try:
        header = json.loads(str(raw))
    except json.JSONDecodeError:
        raise PolicyFileError(f"{path} is not a twolink policy file (no policy header)") \
            from None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise PolicyFileError(f"{path} is not a twolink policy file "
                              f"(format {header.get('format') if isinstance(header, dict) else None!r})")
    version = header.get("format_version")
    if version != FORMAT_VERSION:
        hint = (" (written before policy files carried a sha256); re-synthesise it with "
                "`twolink synthesize`" if isinstance(version, int) and version < FORMAT_VERSION
                else "")
        raise PolicyFileError(f"{path}: unsupported policy format version {version!r}, "
                              f"expected {FORMAT_VERSION}{hint}")
    try:
        agents = header["agents"]
        shapes = {e["name"]: tuple(int(n) for n in e["q_shape"]) for e in agents}
        grids = {e["name"]: Grid.from_dict(e["grid"]) for e in agents}
    except (KeyError, TypeError, ValueError) as exc:
        raise PolicyFileError(f"{path}: malformed twolink policy ({exc})") from None
    for name, grid in grids.items():
        if len(grid.axes) > MAX_AXES:
            raise PolicyFileError(f"{path}: agent {name} reads {len(grid.axes)} inputs, more "
                                  f"than the {MAX_AXES} a policy may have (each state would "
                                  f"weigh 2**{len(grid.axes)} bins)")
    grid_sizes = {name: grid.size for name, grid in grids.items()}
    expected = {f"q_{n}.npy" for n in shapes} | {"header.npy"}
    if names - expected:
        raise PolicyFileError(f"{path}: unexpected members {sorted(names - expected)} in a "
                              f"policy file")
    q_tables = {}
    for name, shape in shapes.items():
        member = f"q_{name}.npy"
        if member not in names:
            raise PolicyFileError(f"{path}: Q-table of agent {name} is missing")
        if len(shape) != 2 or shape[0] != grid_sizes[name] or min(shape) < 1:
            raise PolicyFileError(f"{path}: agent {name}: Q must have shape "
                                  f"({grid_sizes[name]}, N_U), header says {shape}")
        nbytes = 8 * shape[0] * shape[1]
        if nbytes > MAX_Q_BYTES:
            raise PolicyFileError(f"{path}: agent {name}: a Q-table of shape {shape} is "
                                  f"larger than the {MAX_Q_BYTES} bytes a policy may hold")
        _member_size(zf, member, nbytes + _NPY_HEADER_BYTES, path, f"agent {name}'s Q-table",
                     f"a float64 table of shape {shape} needs")
        q = _read_member(zf, member, nbytes, path)
        if q.dtype != np.dtype("<f8"):
            raise PolicyFileError(f"{path}: agent {name}: Q must hold float64 numbers, got "
                                  f"dtype {q.dtype}")
        if q.shape != shape:
            raise PolicyFileError(f"{path}: agent {name}: Q must have shape {shape} "
                                  f"(header), got {q.shape}")
        if not np.all(np.isfinite(q)):
            raise PolicyFileError(f"{path}: agent {name}: Q contains NaN or infinite values")
        q_tables[name] = q
    return header, q_tables


def check_links_match(policy: Policy, links: int, *, name: str | None = None) -> Policy:
    """``policy`` if it is for an arm of ``links`` links, else one clear ValueError line
    naming it (``name``, default its kind) and both numbers of links."""
    n = check_links(links)
    if policy.links != n:
        raise ValueError(f"policy {name or policy.kind} is for a {policy.links}-link arm, "
                         f"the arm has {n} links")
    return policy


def shipped_policies() -> list[str]:
    """Names of the shipped policies (:data:`twolink.policy.registry.SHIPPED`), in report order."""
    return list(SHIPPED)


def policy_with_readout(table: str | os.PathLike, readout) -> Policy:
    """The policy ``table`` (a shipped name or a policy file, :func:`load_policy`) read
    through ``readout`` (a :class:`Readout` or its ``as_dict()``): a design given as data
    over a stored Q-table, as catalogue entries give it. A read-out that is not a dict of
    the read-out's fields is one ValueError line."""
    if isinstance(readout, dict):
        try:
            readout = Readout.from_dict(readout)
        except TypeError as exc:
            raise ValueError(f"readout {readout!r:.80}: {exc}") from None
    return load_policy(table).with_readout(readout, table=str(table))


def load_policy(name_or_path: str | os.PathLike) -> Policy:
    """A shipped policy by name (e.g. ``centralized``: its table read through its
    read-out), a shipped table by its name (:attr:`ShippedPolicy.table
    <twolink.policy.registry.ShippedPolicy.table>`, e.g. ``centralized_simplified``: the
    Q-tables with no read-out) or a policy file by path."""
    text = str(name_or_path)
    if os.sep not in text and not text.endswith(".npz"):
        if text in SHIPPED:
            entry = SHIPPED[text]
            policy = Policy.load(entry.file)
            if entry.table_owner == text:
                return policy
            return policy.with_readout(entry.readout(), table=entry.table)
        stored = next((p for p in SHIPPED.values() if p.table == text), None)
        if stored is not None:
            return Policy.load(stored.file).with_readout(Readout(), table=text)
        raise PolicyFileError(f"unknown policy {text!r}; shipped policies: "
                              f"{', '.join(SHIPPED)} (or a shipped table, or a .npz path)")
    return Policy.load(Path(text))
