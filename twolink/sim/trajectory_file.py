"""Saving rollouts: a long-format CSV and an NPZ archive with a JSON header.

Both hold, for every (policy, plant) run, the times t_k, states x_k, the commands u_k
held over [t_k, t_k + Ts) and the rewards r_k of (15) and (17) reached at t_k (the CSV
leaves u empty on the last sample and r empty on the first).
"""
from __future__ import annotations

import csv
import io
import json
import os
from pathlib import Path

import numpy as np

from twolink.arm.parameters import state_names
from twolink.artifacts import atomic_path, provenance, write_text
from twolink.sim.rollout import Trajectory

FORMAT = "twolink-trajectories"


def csv_columns(links: int = 2) -> tuple:
    """The CSV header of an arm of ``links`` links: policy, plant, k, t, the 2N state
    components, tau1..tauN, the reward r of (15) and the per-link rewards r1..rN of (17)."""
    torques = tuple(f"tau{i}" for i in range(1, links + 1))
    rewards = tuple(f"r{i}" for i in range(1, links + 1))
    return ("policy", "plant", "k", "t", *state_names(links), *torques, "r", *rewards)


#: The CSV header of the paper's two-link arm.
CSV_COLUMNS = csv_columns(2)


def _check(runs: dict) -> int:
    """The number of links of ``runs`` (one for all), or a ValueError."""
    if not runs:
        raise ValueError("no trajectories to save")
    links = set()
    for key, tr in runs.items():
        if not isinstance(tr, Trajectory) or tr.x.ndim != 2:
            raise ValueError(f"{key}: expected a single (unbatched) trajectory")
        links.add(tr.x.shape[-1] // 2)
    if len(links) > 1:
        raise ValueError(f"trajectories of arms with {sorted(links)} links cannot share a file")
    return links.pop()


def to_csv_text(runs: dict) -> str:
    """CSV text of ``{(policy, plant): Trajectory}``, one row per sample."""
    n = _check(runs)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(csv_columns(n))
    for (policy, plant), tr in runs.items():
        for k in range(len(tr.t)):
            u = tr.u[k] if k < tr.steps else ("",) * n
            r = (tr.r[k - 1], *tr.r_links[k - 1]) if k > 0 else ("",) * (n + 1)
            w.writerow([policy, plant, k, f"{tr.t[k]:.6g}", *(repr(float(v)) for v in tr.x[k]),
                        *(v if v == "" else repr(float(v)) for v in u),
                        *(v if v == "" else repr(float(v)) for v in r)])
    return buf.getvalue()


def save_csv(path: os.PathLike, runs: dict) -> Path:
    return write_text(path, to_csv_text(runs))


def save_npz(path: os.PathLike, runs: dict, *, meta: dict | None = None) -> Path:
    """NPZ with arrays ``<policy>/<plant>/{t,x,u,r,r_links}`` and a JSON ``header`` whose
    ``runs`` list [policy label, plant, policy kind] per run."""
    _check(runs)
    arrays = {}
    for (policy, plant), tr in runs.items():
        for name in ("t", "x", "u", "r", "r_links"):
            arrays[f"{policy}/{plant}/{name}"] = getattr(tr, name)
    header = {"format": FORMAT, "runs": [[*k, tr.kind] for k, tr in runs.items()],
              "meta": meta or {}, "provenance": provenance()}
    path = Path(path)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, header=np.array(json.dumps(header, sort_keys=True)),
                                **arrays)
    return path


def _kind(label: str) -> str:
    """The kind of a run saved before kinds were recorded: a shipped policy's, else ''."""
    from twolink.policy.registry import SHIPPED
    return SHIPPED[label].kind if label in SHIPPED else ""


def load_npz(path: os.PathLike) -> dict:
    """The runs saved by :func:`save_npz`, as ``{(policy, plant): Trajectory}``."""
    with np.load(path, allow_pickle=False) as npz:
        header = json.loads(str(npz["header"]))
        if header.get("format") != FORMAT:
            raise ValueError(f"{path} is not a twolink trajectory file")
        out = {}
        for run in header["runs"]:
            pol, pl = run[:2]
            kind = run[2] if len(run) > 2 else _kind(pol)
            out[(pol, pl)] = Trajectory(*(npz[f"{pol}/{pl}/{n}"]
                                          for n in ("t", "x", "u", "r", "r_links")),
                                        plant=pl, label=pol, kind=kind)
        return out
