"""Run the benchmark suite: ``python -m benchmarks.run [--quick] [--json PATH [--merge]]``.

Quick mode (CI, well under two minutes on 2 cores) and full mode (the README's figures)
measure the same rows; full mode repeats more, uses bigger batches, runs the finer
grids and pymdptoolbox's complete constructor. Every ratio is measured in this run on
the same inputs. The JSON holds the rows, per-section summaries and the machine.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

if __package__ in (None, ""):                       # `python benchmarks/run.py`
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.common import Row, available_ram_bytes, format_table, total_ram_bytes  # noqa: E402
from twolink.artifacts import provenance, write_json  # noqa: E402

MODES = {
    "quick": {"repeats": 2, "sweep_repeats": 3, "full_setup": False,
              "central": (1, 2), "decentral": (1, 2, 3),
              "batch": 64, "frames": 10, "render_repeats": 1,
              "vector_samples": 20, "eval_states": 13,
              "eval_horizon": 2.0, "mpc_quick": True,
              "board_plants": 12, "board_states": 13, "board_repeats": 2,
              "board_through": ("lqr",)},
    "full": {"repeats": 5, "sweep_repeats": 15, "full_setup": True,
             "central": (1, 2, 3, 4), "decentral": (1, 2, 3, 6),
             "batch": 256, "frames": 40, "render_repeats": 3,
             "vector_samples": 100, "eval_states": 65,
             "eval_horizon": 5.0, "mpc_quick": False,
             "board_plants": 32, "board_states": 65, "board_repeats": 2,
             "board_through": ("lqr", "decentralized_locked_gain")},
}
SECTIONS = ("startup", "synthesis", "scaling", "rollouts", "rendering", "vector_env",
            "evaluation", "mpc", "training", "leaderboard")


def machine() -> dict:
    """Provenance plus the CPU model and memory."""
    info = provenance()
    try:
        with open("/proc/cpuinfo") as f:
            names = [line.split(":", 1)[1].strip() for line in f if line.startswith("model name")]
        info["cpu_model"] = names[0] if names else None
    except OSError:
        info["cpu_model"] = None
    info["ram_bytes"] = total_ram_bytes()
    info["ram_available_bytes"] = available_ram_bytes()
    try:
        import os
        info["load_average"] = os.getloadavg()
    except OSError:
        info["load_average"] = None
    return info


def run(mode: str = "quick", sections=SECTIONS, *, progress=print) -> dict:
    """Measure the chosen sections; returns {"rows", "summary", "machine", ...}."""
    from benchmarks import rollouts, synthesis

    cfg = MODES[mode]
    rows: list[Row] = []
    summary, seconds = {}, {}
    for section in sections:
        progress(f"[bench] {section} ...", file=sys.stderr)
        t0 = time.perf_counter()
        if section == "startup":
            from benchmarks import startup
            r, summary[section] = startup.bench_startup(repeats=5)
        elif section == "synthesis":
            r, summary[section] = synthesis.bench_synthesis(
                repeats=cfg["repeats"], sweep_repeats=cfg["sweep_repeats"],
                full_setup=cfg["full_setup"])
        elif section == "scaling":
            from benchmarks import synthesis_scaling
            r, summary[section] = synthesis_scaling.bench_scaling(cfg["central"],
                                                                  cfg["decentral"])
        elif section == "rollouts":
            r, summary[section] = rollouts.bench_rollouts(batch=cfg["batch"],
                                                          repeats=cfg["repeats"])
        elif section == "rendering":
            from benchmarks import render
            r, summary[section] = render.bench_render(frames=cfg["frames"],
                                                      repeats=cfg["render_repeats"])
        elif section == "vector_env":
            from benchmarks import vector_env
            r, summary[section] = vector_env.bench_vector_env(
                num_envs=64, samples=cfg["vector_samples"], repeats=cfg["repeats"])
        elif section == "evaluation":
            from benchmarks import evaluation
            r, summary[section] = evaluation.bench_evaluation(states=cfg["eval_states"],
                                                              horizon=cfg["eval_horizon"],
                                                              repeats=cfg["repeats"])
        elif section == "leaderboard":
            from benchmarks import leaderboard
            r, summary[section] = leaderboard.bench_leaderboard(
                plants=cfg["board_plants"], states=cfg["board_states"],
                repeats=cfg["board_repeats"], through=cfg["board_through"])
        elif section == "training":
            from benchmarks import training
            r, summary[section] = training.bench_training(
                n_steps=64 if mode == "quick" else 128, updates=1 if mode == "quick" else 3)
        elif section == "mpc":
            from benchmarks import mpc
            r, summary[section] = (mpc.bench_mpc(states=mpc.QUICK_STATES, duration=1.0)
                                   if cfg["mpc_quick"] else mpc.bench_mpc())
        else:
            raise ValueError(f"unknown benchmark section {section!r}; choose from "
                             f"{', '.join(SECTIONS)}")
        rows += r
        seconds[section] = time.perf_counter() - t0
    return {"mode": mode, "config": {k: list(v) if isinstance(v, tuple) else v
                                     for k, v in cfg.items()},
            "command": "python -m benchmarks.run" + (" --quick" if mode == "quick" else ""),
            "machine": machine(), "seconds": seconds,
            "rows": [r.as_dict() for r in rows], "summary": _jsonable(summary)}


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if hasattr(obj, "item"):
        return obj.item()
    return obj


def _section(row: dict) -> str:
    return row["section"].split(":", 1)[0]


def _earlier(path: Path, measured) -> dict | None:
    """The results file at ``path`` (None if there is none) less the sections
    ``measured``; a ValueError naming the file if it is no results file."""
    if not path.is_file():
        return None
    import json
    try:
        data = json.loads(path.read_text())
        kept = sorted({_section(r) for r in data["rows"]} - set(measured))
        return {"rows": [r for r in data["rows"] if _section(r) in kept],
                "summary": {k: v for k, v in data["summary"].items() if k in kept},
                "seconds": {k: v for k, v in data["seconds"].items() if k in kept},
                "earlier": {**{k: data[k] for k in ("mode", "command", "machine")},
                            "sections": kept}}
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        raise ValueError(f"{path}: not a benchmark results file ({exc})") from None


def _merged(result: dict, earlier: dict) -> dict:
    """This run's ``result`` with the ``earlier`` file's other sections (their rows
    first, in their order), and under ``earlier`` the run they came from."""
    return {**result, "rows": earlier["rows"] + result["rows"],
            "summary": {**earlier["summary"], **result["summary"]},
            "seconds": {**earlier["seconds"], **result["seconds"]},
            "earlier": earlier["earlier"]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.run",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="CI mode: fewer repeats, small grids")
    ap.add_argument("--json", type=Path, help="write the results as JSON to this path")
    ap.add_argument("--only", nargs="+", choices=SECTIONS, default=list(SECTIONS),
                    help="run only these sections")
    ap.add_argument("--merge", action="store_true",
                    help="with --json: keep the sections of the existing file that this "
                         "run does not measure (recorded with their own run's machine)")
    args = ap.parse_args(argv)
    if args.json is not None and not args.json.parent.is_dir():
        ap.error(f"cannot write {args.json}: directory {args.json.parent} does not exist")
    if args.merge and args.json is None:
        ap.error("--merge needs --json PATH")
    earlier = _earlier(args.json, args.only) if args.merge else None
    t0 = time.perf_counter()
    result = run("quick" if args.quick else "full", args.only)
    result["seconds"]["total"] = time.perf_counter() - t0
    m = result["machine"]
    print(f"twolink benchmarks, {result['mode']} mode: {m['cpu_model']}, {m['cpu_count']} cores, "
          f"{(m['ram_bytes'] or 0) / 2**30:.1f} GiB RAM, load {m['load_average']}")
    print(format_table([Row(**r) for r in result["rows"]]))
    print(f"\n{result['seconds']['total']:.1f} s in all")
    if args.json is not None:
        write_json(args.json, result if earlier is None else _merged(result, earlier))
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
