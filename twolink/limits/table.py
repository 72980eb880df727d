"""The results: one :class:`Limit` per state, a :class:`LimitTable` per model, their JSON
form (the shipped ``data/limits.json``), the open-loop replay on a plant and the text
table the command line prints."""
from __future__ import annotations

import dataclasses
import json
import math

import numpy as np

from twolink.arm.parameters import TS
from twolink.limits.symbolic import check_model

#: The format tag of the JSON file.
FORMAT = "twolink-limits/1"


@dataclasses.dataclass(frozen=True)
class Limit:
    """The physical limit T*(x0) on one model, in samples of Ts.

    ``lower``: the search's lower bound: no initial guess found the band reachable at
    sample ``lower - 1`` (``max_samples + 1`` when nothing reached it within
    ``max_samples``). ``upper``: the torque sequence ``torques`` (``upper + hold`` rows,
    zero torque after them) brings the numpy model into the goal band at sample
    ``upper`` and keeps it there to the end of the horizon (None when the search found no
    such sequence). T*(x0) lies in [lower, upper]; ``samples`` is ``upper``.
    ``winding`` (k1, k2): the band is reached around 2 pi k_i (angles unwrapped from the
    wrapped x0). ``reach_slack`` and ``hold_slack``: IPOPT's slack s at the bound (s <= 0
    is inside the band; -1 the band's centre at rest). ``mujoco_settle``: the settle time
    (s) of ``torques`` replayed open loop on the MuJoCo plant over the 5 s horizon (inf:
    it does not settle; None: not replayed). ``mirror_of``: the row of the table whose
    mirror image -x0 this state is (both models are odd, f(-x, -u) = -f(x, u), so the
    row's torques negated reach the band in the same N; they are replayed on the numpy
    model all the same), None if it was searched itself.
    """

    x0: tuple
    model: str
    lower: int
    upper: int | None
    winding: tuple = (0, 0)
    torques: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 2)))
    reach_slack: float | None = None
    hold_slack: float | None = None
    solves: int = 0
    time_s: float = 0.0
    mujoco_settle: float | None = None
    mirror_of: int | None = None

    @property
    def samples(self) -> int | None:
        """The number of samples achieved (``upper``); T*(x0) when :attr:`exact`."""
        return self.upper

    @property
    def seconds(self) -> float | None:
        """``samples`` x Ts."""
        return None if self.upper is None else round(self.upper * TS, 10)

    @property
    def exact(self) -> bool:
        """lower == upper: the search pins T*(x0) down."""
        return self.upper is not None and self.lower == self.upper

    def to_dict(self) -> dict:
        return {"x0": [float(v) for v in self.x0], "model": self.model,
                "lower": self.lower, "upper": self.upper, "seconds": self.seconds,
                "winding": list(self.winding), "reach_slack": self.reach_slack,
                "hold_slack": self.hold_slack, "solves": self.solves,
                "time_s": round(self.time_s, 3),
                "mujoco_settle_s": _finite_or_str(self.mujoco_settle),
                "mirror_of": self.mirror_of,
                "torques": np.asarray(self.torques, float).tolist()}

    @classmethod
    def from_dict(cls, d: dict) -> "Limit":
        settle = d.get("mujoco_settle_s")
        return cls(x0=tuple(float(v) for v in d["x0"]), model=check_model(d["model"]),
                   lower=int(d["lower"]),
                   upper=None if d.get("upper") is None else int(d["upper"]),
                   winding=tuple(int(v) for v in d.get("winding", (0, 0))),
                   torques=np.asarray(d.get("torques") or np.zeros((0, 2)),
                                      float).reshape(-1, 2),
                   reach_slack=d.get("reach_slack"), hold_slack=d.get("hold_slack"),
                   solves=int(d.get("solves", 0)), time_s=float(d.get("time_s", 0.0)),
                   mujoco_settle=None if settle is None else float(settle),
                   mirror_of=None if d.get("mirror_of") is None else int(d["mirror_of"]))


def _finite_or_str(v):
    """JSON has no inf: a non-finite float as the string "inf"."""
    if v is None or math.isfinite(v):
        return v
    return str(v)


@dataclasses.dataclass(frozen=True)
class LimitTable:
    """The limits of many states on one model, with the provenance of the run."""

    model: str
    rows: tuple
    provenance: dict = dataclasses.field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.rows)

    def __getitem__(self, i) -> Limit:
        return self.rows[i]

    @property
    def states(self) -> np.ndarray:
        return np.array([r.x0 for r in self.rows], float).reshape(-1, 4)

    @property
    def samples(self) -> np.ndarray:
        """``upper`` of each row (-1 where none was found)."""
        return np.array([-1 if r.upper is None else r.upper for r in self.rows])

    @property
    def lower(self) -> np.ndarray:
        return np.array([r.lower for r in self.rows])

    def median_seconds(self) -> float:
        """The median of ``seconds`` over the rows (a row without an upper bound counts
        as infinite)."""
        return float(np.median([np.inf if r.upper is None else r.seconds
                                for r in self.rows]))

    def mismatches(self) -> list:
        """Indices of the rows whose lower and upper bounds differ (or lack an upper)."""
        return [i for i, r in enumerate(self.rows) if not r.exact]

    def summary(self) -> dict:
        settle = [r.mujoco_settle for r in self.rows if r.mujoco_settle is not None]
        return {"model": self.model, "states": len(self.rows),
                "median_s": self.median_seconds(),
                "min_s": min((r.seconds for r in self.rows if r.upper is not None),
                             default=None),
                "max_s": max((r.seconds for r in self.rows if r.upper is not None),
                             default=None),
                "exact": len(self.rows) - len(self.mismatches()),
                "mismatches": self.mismatches(),
                "mujoco_settled_by_limit": sum(1 for r in self.rows
                                               if r.mujoco_settle is not None
                                               and r.seconds is not None
                                               and r.mujoco_settle <= r.seconds + 1e-9),
                "mujoco_replayed": len(settle)}

    def to_dict(self) -> dict:
        return {"provenance": dict(self.provenance), "summary": self.summary(),
                "rows": [r.to_dict() for r in self.rows]}

    @classmethod
    def from_dict(cls, model: str, d: dict) -> "LimitTable":
        return cls(model=check_model(model),
                   rows=tuple(Limit.from_dict(r) for r in d["rows"]),
                   provenance=dict(d.get("provenance", {})))


def tables_to_json(tables, provenance: dict) -> str:
    """The JSON text of the shipped file: one entry per model, one line per row."""
    rows = []
    models = {}
    for t in tables:
        d = t.to_dict()
        d["rows"], first = [f"@@row{len(rows) + i}@@" for i in range(len(d["rows"]))], d["rows"]
        rows += first
        models[t.model] = d
    text = json.dumps({"format": FORMAT, "provenance": provenance, "models": models},
                      indent=1, sort_keys=True, allow_nan=False)
    for i, row in enumerate(rows):
        text = text.replace(f'"@@row{i}@@"', json.dumps(row, sort_keys=True, allow_nan=False),
                            1)
    return text + "\n"


def tables_from_json(text: str, source: str = "limits file") -> dict:
    """{model: LimitTable} of the JSON text written by :func:`tables_to_json`; the
    file's provenance is merged into each table's. Text that is not JSON or not such a
    table gives a one-line ValueError beginning with ``source`` (the file's path)."""
    try:
        data = json.loads(text)
    except ValueError as exc:
        raise ValueError(f"{source}: not valid JSON ({exc})") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        got = data.get("format") if isinstance(data, dict) else type(data).__name__
        raise ValueError(f"{source}: not a limits file of format {FORMAT} (format "
                         f"{got!r})")
    out = {}
    try:
        for model, entry in data["models"].items():
            table = LimitTable.from_dict(model, entry)
            out[model] = dataclasses.replace(
                table, provenance={**data.get("provenance", {}), **table.provenance})
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise ValueError(f"{source}: not a valid limits table ({type(exc).__name__}: "
                         f"{exc})") from None
    return out


class OpenLoop:
    """A policy that plays fixed torque sequences, one per batch row, then zero: for
    :func:`twolink.sim.rollout.rollout` (it counts its calls: one per sample)."""

    def __init__(self, torques):
        self.torques = np.asarray(torques, float)      # (B, K, 2) or (K, 2)
        self.k = 0

    def reset(self, rows: int | None = None) -> None:
        """Back to the first sample (a rollout calls it before it starts)."""
        self.k = 0

    def __call__(self, x):
        x = np.asarray(x)
        k, self.k = self.k, self.k + 1
        if k < self.torques.shape[-2]:
            return np.broadcast_to(self.torques[..., k, :], x.shape[:-1] + (2,)).copy()
        return np.zeros(x.shape[:-1] + (2,))


def replay_on(plant_name: str, limits, *, duration: float = 5.0, params=None):
    """The torques of ``limits`` (rows with an upper bound) replayed open loop from their
    x0 on the plant ``plant_name`` over ``duration`` seconds: (indices, settle times)."""
    from twolink.arm.parameters import TABLE_I
    from twolink.sim.metrics import settle_time
    from twolink.sim.plants import make_plant
    from twolink.sim.rollout import rollout

    rows = [i for i, r in enumerate(limits) if r.upper is not None]
    if not rows:
        return rows, np.zeros(0)
    steps = int(round(duration / TS))
    u = np.zeros((len(rows), max(steps, 1), 2))
    for j, i in enumerate(rows):
        t = np.asarray(limits[i].torques, float)[:steps]
        u[j, :len(t)] = t
    x0 = np.array([limits[i].x0 for i in rows], float)
    with make_plant(plant_name, TABLE_I if params is None else params) as plant:
        traj = rollout(OpenLoop(u), plant, x0, duration=duration, label="time_optimal")
    return rows, settle_time(traj)


def format_table(tables: dict) -> str:
    """The text table of one or more models' limits (same states in each)."""
    models = list(tables)
    first = tables[models[0]]
    head = f"{'theta1':>8} {'theta2':>8} {'dtheta1':>8} {'dtheta2':>8}"
    for m in models:
        head += f" | {m + ' N':>14} {'s':>6} {'wind':>6} {'mujoco':>7}"
    lines = [head, "-" * len(head)]
    for i, row in enumerate(first.rows):
        line = " ".join(f"{v:+8.3f}" for v in row.x0)
        for m in models:
            r = tables[m].rows[i]
            n = "-" if r.upper is None else str(r.upper)
            bounds = n if r.exact else f"{r.lower}..{n}"
            secs = "-" if r.seconds is None else f"{r.seconds:.2f}"
            settle = "-" if r.mujoco_settle is None else (
                "never" if not math.isfinite(r.mujoco_settle) else f"{r.mujoco_settle:.2f}")
            wind = f"{r.winding[0]:+d},{r.winding[1]:+d}"
            line += f" | {bounds:>14} {secs:>6} {wind:>6} {settle:>7}"
        lines.append(line)
    lines.append("")
    for m in models:
        s = tables[m].summary()
        lines.append(f"{m}: {s['states']} states, median {s['median_s']:.2f} s, "
                     f"lower == upper in {s['exact']}"
                     + (f", differ at rows {s['mismatches']}" if s['mismatches'] else "")
                     + (f"; MuJoCo replay settles by the limit in "
                        f"{s['mujoco_settled_by_limit']} of {s['mujoco_replayed']}"
                        if s['mujoco_replayed'] else ""))
    return "\n".join(lines)
