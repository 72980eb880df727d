"""One synthesis of the scaling study, measured: its policy, wall and CPU seconds and peak
memory, here (tracemalloc) or in a fresh process (:data:`PEAK_METHODS`).
"""
from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import multiprocessing
import time
import tracemalloc
from typing import Optional

from tqdm import tqdm

from twolink.arm.parameters import TABLE_I, links_parameters
from twolink.policy.registry import SHIPPED

#: The torque levels per joint of the ``decentralized_levels`` cells.
LEVER_LEVELS = 5
#: The read-out of the ``decentralized_argmax`` cells (:data:`LEVER_LEVELS` levels): the
#: argmax of Q beyond this many degrees (twolink.policy.readout). Chosen among 10, 20,
#: 30 and 45 on the tapered five-link arm's development poses, random_poses(5, 64,
#: 7100 + 5) and random_poses(5, 256, 7200 + 5): the most successes at 8 s summed.
LEVER_ARGMAX_DEG = 20.0

#: How the peak memory of one synthesis is measured: ``"process"`` runs it in a fresh
#: process, after the imports and a warm-up (the two-link decentralized synthesis, which
#: loads the compiled kernels: about 125 MiB of numba's own), gives freed heap back
#: (``malloc_trim``), resets the peak resident set (Linux: /proc/self/clear_refs) and
#: takes its growth (VmHWM) over the resident set just before the synthesis;
#: ``"tracemalloc"`` runs it here and takes tracemalloc's peak (numpy arrays and Python
#: objects; not numba's own allocations), faster but narrower, and it slows
#: Python-heavy code a little.
PEAK_METHODS = ("process", "tracemalloc")


def check_peak_method(method: str) -> str:
    if method not in PEAK_METHODS:
        raise ValueError(f"unknown peak-memory method {method!r}; choose from "
                         f"{', '.join(PEAK_METHODS)}")
    return method


@dataclasses.dataclass
class Synthesis:
    """One synthesis, measured: the whole call's wall and CPU seconds (CPU of every
    thread of the process), its peak memory and how that was measured, the Q-values and
    non-zeros of T over all agents, and per agent (in synthesis order: agent N first) its
    name, Q size, non-zeros and sweeps; whether the policy equals the shipped file it
    rebuilds (:func:`shipped_counterpart`; None if there is none) bit for bit."""

    wall_seconds: float
    cpu_seconds: float
    peak_bytes: int
    peak_method: str
    q_values: int
    nnz: int
    agents: list
    construction: str
    matches_shipped_policy: Optional[bool] = None
    shipped_policy: Optional[str] = None

    @property
    def sweeps(self) -> dict:
        return {a["name"]: a["sweeps"] for a in self.agents}


def shipped_counterpart(links: int, rule: str, scheme: str) -> Optional[str]:
    """The registry's shipped policy that a cell rebuilds, if any: ``centralized_full`` /
    ``decentralized_full`` for two links, else a nominal (not robust) entry of the same
    kind, links and rule on the full model (``decentralized_3link``)."""
    if links == 2:
        return f"{scheme}_full"
    return next((name for name, e in SHIPPED.items()
                 if (e.links, e.rule, e.kind, e.model, e.robust)
                 == (links, rule, scheme, "full", None)), None)


def cell_policy(links: int, rule: str, scheme: str, max_bytes: int):
    """The policy of one cell and a line saying how it was built."""
    if links == 2:
        name = f"{scheme}_full"
        entry = SHIPPED[name]
        from twolink.synthesis.synthesize import synthesize
        return (synthesize(entry.kind, TABLE_I, **entry.synthesis_options()),
                f"{name} (registry): {entry.description}")
    p = links_parameters(links, rule)
    if scheme in ("decentralized", "decentralized_levels", "decentralized_argmax"):
        from twolink.synthesis.links_decentralized import synthesize_links
        from twolink.policy.readout import Readout
        levels = {"levels": LEVER_LEVELS} if scheme != "decentralized" else {}
        if scheme == "decentralized_argmax":
            levels["readout"] = Readout(argmax_beyond_deg=LEVER_ARGMAX_DEG)
        policy = synthesize_links(p, **levels)
        c = ", ".join(f"{k}={v}" for k, v in policy.meta.get("construction", {}).items())
        c += "".join(f", {k}={v}" for k, v in policy.meta.get("design", {}).items())
        if "readout" in policy.meta:
            c += f", argmax beyond {policy.meta['readout']['argmax_beyond_deg']:g} deg"
        return policy, f"one agent per joint on the full N-link model " \
                       f"(twolink.synthesis.links_decentralized.synthesize_links; {c})"
    from twolink.synthesis.links_centralized import synthesize_centralized
    return synthesize_centralized(p, max_bytes=max_bytes), \
        "the centralized policy (16) on the full N-link model " \
        "(twolink.synthesis.links_centralized.synthesize_centralized)"


def _agent_info(agent) -> dict:
    info = agent.info
    return {"name": agent.name, "q_size": int(agent.q.size),
            "nnz": int(info.get("transition_nnz", info.get("nnz", 0))),
            "sweeps": int(info["iterations"]),
            "seconds": float(info["seconds"]) if "seconds" in info else None}


def _status_bytes(key: str) -> int:
    """A ``Vm...`` line of /proc/self/status in bytes."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1]) * 1024
    raise OSError(f"/proc/self/status has no {key}")


def _reset_high_water() -> bool:
    """Give freed heap back to the system and reset this process's peak resident set
    (VmHWM) to the current one; False where Linux does not allow it."""
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


@contextlib.contextmanager
def _peak(method: str):
    """Yield a dict whose ``"bytes"`` holds the peak after the block (see
    :data:`PEAK_METHODS`)."""
    out = {}
    if method == "tracemalloc":
        started = not tracemalloc.is_tracing()
        if started:
            tracemalloc.start()
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        try:
            yield out
            out["bytes"] = max(0, tracemalloc.get_traced_memory()[1] - base)
        finally:
            if started:
                tracemalloc.stop()
    else:
        if not _reset_high_water():
            raise OSError("cannot reset the peak resident set (/proc/self/clear_refs); "
                          "measure with tracemalloc instead")
        base = _status_bytes("VmRSS")
        yield out
        out["bytes"] = max(0, _status_bytes("VmHWM") - base)


def synthesize_measured(links: int, rule: str, scheme: str, *, max_bytes: int,
                        peak: str = "tracemalloc"):
    """Synthesise one cell here and measure it: ``(policy, Synthesis)``. With
    ``peak="process"`` the figure is only per-synthesis in a fresh process (as
    :func:`twolink.studies.scaling.measure.measure`
    runs it)."""
    from twolink.studies.reproduce.measure import matches_shipped

    with _peak(check_peak_method(peak)) as mem:
        cpu0, t0 = time.process_time(), time.perf_counter()
        policy, how = cell_policy(links, rule, scheme, max_bytes)
        wall, cpu = time.perf_counter() - t0, time.process_time() - cpu0
    agents = [_agent_info(a) for a in policy.agents]
    name = shipped_counterpart(links, rule, scheme)
    shipped = None if name is None else matches_shipped(name, policy)
    return policy, Synthesis(wall, cpu, int(mem["bytes"]), peak,
                             sum(a["q_size"] for a in agents),
                             sum(a["nnz"] for a in agents), agents, how, shipped, name)


class ProcessDied(RuntimeError):
    """The fresh process of a cell ended without an answer (killed, out of memory)."""


def _child(conn, fn, args) -> None:
    import threading
    tqdm.set_lock(threading.RLock())         # no multiprocessing lock for a silent bar
    try:
        answer = ("ok", fn(*args))
    except BaseException as exc:             # noqa: BLE001 - handed to the parent
        answer = ("error", exc)
    try:
        conn.send(answer)
    except Exception:                        # an exception that does not pickle
        conn.send(("error", RuntimeError(f"{type(answer[1]).__name__}: {answer[1]}")))
    finally:
        conn.close()


def in_fresh_process(fn, args):
    """``fn(*args)`` in a freshly spawned process; its exception re-raised here. The
    process is ended if this one is interrupted or terminated."""
    ctx = multiprocessing.get_context("spawn")
    receive, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(send, fn, args), daemon=True)
    proc.start()
    send.close()
    try:
        try:
            status, value = receive.recv()
        except EOFError:
            proc.join()
            code = proc.exitcode
            why = f"signal {-code}" if code is not None and code < 0 else f"exit code {code}"
            raise ProcessDied(f"the synthesis process ended with {why} before answering"
                              + (" (killed: out of memory?)" if code == -9 else "")) from None
    finally:
        if proc.is_alive():
            proc.terminate()
        proc.join()
        receive.close()
    if status == "error":
        raise value
    return value

