"""Learned agents for the challenge levels: PPO, SAC, IPPO and MAPPO trained under a level.

``python docs/studies/challenge_agents.py [--algos ppo sac ippo mappo_local] [--levels medium hard]
[--seeds 1 2 3] [--steps N] [--work DIR]`` runs ``twolink train --algo ALGO --challenge
LEVEL --history 3 --action-rate 1 --steps N --seed S --eval-every E`` for every algorithm,
level and seed, one run at a time, each resumed from its last checkpoint when a previous
call was interrupted and skipped when finished (PPO: 0.8 M steps, an evaluation every
0.2 M; SAC: 0.3 M, every 50 k; IPPO and MAPPO (``mappo_local``) with ``local``
observations: 1.2 M, every 0.1 M;
:data:`RECIPES`; ``--steps`` overrides them). After every
finished run it copies the run's ``curve.json`` into
``renders/challenge_agents/<algo>_<level>_seed<S>.json`` (SAC's mixed
runs ``sac_mixed_ag<G>_seed<S>``,
:func:`twolink.control.learned.challenge_stem`; the gain-1 runs ``sac_mixed_seed<S>``
stay as a lever) and picks, per algorithm and
level, per seed its best agent (the curve's best point, kept by ``twolink train``; the
final agent of a run that kept none), then the seed whose pick scored most on the curve's
own evaluation (the level on 8 plants of seed 20061122: the training seeds' side, never
the leaderboard's seed 2026), copying that agent to ``renders/challenge_agents/<algo>_<level>.zip`` (IPPO's
``.marl.pt``), the file the
catalogue's ``<algo>_<level>`` names, and the choice to ``<algo>_<level>.selection.json``.
Training seeds 1-3 are neither 2026 nor 20061122 (``twolink train`` refuses those under a
challenge). What each run cost (steps, CPU, wall) is the ``Cost of learning`` section of
the leaderboard (:func:`twolink.control.learned.learning_cost`, read from the curves
copied here).
"""
from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from twolink.artifacts import write_json  # noqa: E402
from twolink.control.learned import MIXED_GAIN, challenge_stem  # noqa: E402

OUT = Path("renders/challenge_agents")
#: Per algorithm: the options every run shares (beside level, seed and steps), its
#: default steps and the suffix of its agent file. IPPO and MAPPO (``mappo_local``; its
#: critics see the whole arm while training) are decentralized with ``local``
#: observations (each joint's agent reads only its own joint), their policy noise held at
#: 0.2 or more (``--std-floor``: without it the agents' means learn torques that jump
#: between the limits, the training guide).
RECIPES = {
    "ppo": (["--algo", "ppo", "--history", "3", "--action-rate", "1",
             "--eval-every", "200000"], 800_000, ".zip"),
    "sac": (["--algo", "sac", "--history", "3", "--action-rate", "1",
             "--eval-every", "50000"], 300_000, ".zip"),
    "ippo": (["--algo", "ippo", "--observe", "local", "--history", "3", "--action-rate",
              "1", "--std-floor", "0.2", "--eval-every", "100000"], 1_200_000, ".marl.pt"),
    "mappo_local": (["--algo", "mappo", "--observe", "local", "--history", "3",
                     "--action-rate", "1", "--std-floor", "0.2", "--eval-every", "100000"],
                    1_200_000, ".marl.pt"),
}

#: ``--levels mixed``: the levels a mixed run trains under side by side (arm i under level
#: i mod 3, ``twolink train --challenge none+medium+hard``), so one agent meets the nominal
#: arm and both scored levels; its arms per batch per algorithm (a multiple of three). A
#: mixed run of PPO or SAC learns from ``--reward shaped_time`` (the shaped reward less one
#: per sample outside the goal band), the minimum-time term for the nominal settle target.
#: SAC's mixed runs also take an action gain (``--action-gain``,
#: :data:`twolink.control.learned.MIXED_GAIN`).
MIXED = ("none+medium+hard", {"ppo": 18, "sac": 9, "ippo": 18, "mappo_local": 18})


def _challenge_options(algo: str, level: str) -> list[str]:
    if level == "mixed":
        reward = ["--reward", "shaped_time"] if algo in ("ppo", "sac") else []
        gain = ["--action-gain", f"{MIXED_GAIN[algo]:g}"] if algo in MIXED_GAIN else []
        return ["--challenge", MIXED[0], "--envs", str(MIXED[1][algo]), *reward, *gain]
    return ["--challenge", level]


def _state(folder: Path) -> str:
    try:
        record = json.loads((folder / "curve.json").read_text())
        if record.get("done") and (folder / record["agent"]).is_file():
            return "finished"
    except (OSError, ValueError, KeyError):
        pass
    return "interrupted" if (folder / "checkpoint.pt").is_file() else "new"


def run(algo: str, level: str, seed: int, steps: int, work: Path) -> dict:
    """Train (or resume, or reuse) one run; its curve record, copied under :data:`OUT`,
    and its folder."""
    folder = work / f"{challenge_stem(algo, level)}_seed{seed}"
    state = _state(folder)
    if state != "finished":
        cmd = [sys.executable, "-m", "twolink.cli", "train", *RECIPES[algo][0],
               *_challenge_options(algo, level), "--seed", str(seed), "--steps", str(steps),
               "-o", str(folder)]
        if state == "interrupted":
            cmd.append("--resume")
        print(f"{folder.name}: {'resuming' if state == 'interrupted' else 'training'}",
              flush=True)
        subprocess.run(cmd, check=True)
    record = json.loads((folder / "curve.json").read_text())
    write_json(OUT / f"{folder.name}.json", record)
    return {"record": record, "folder": folder}


def candidate(d: dict) -> dict:
    """A seed's candidate: its best agent (the curve's best point, ``twolink train``'s
    ``best``) where the run kept one, else its final agent; its score on the curve."""
    r = d["record"]
    if r.get("best"):
        b = r["best"]
        return {"agent": d["folder"] / b["agent"], "which": "best", "steps": b["steps"],
                "successes": b["successes"], "n": b["n"]}
    last = r["curve"][-1]
    return {"agent": d["folder"] / r["agent"], "which": "final", "steps": last["steps"],
            "successes": last["successes"], "n": last["n"]}


def select(algo: str, level: str, done: list) -> None:
    """Ship the candidate of ``done`` (:func:`candidate`, one per seed) that scored most on
    its curve's evaluation as ``<algo>_<level>`` (the lower seed of equals), and the choice
    beside it."""
    seeds = {d["record"]["config"]["seed"]: candidate(d) for d in done}
    chosen = max(seeds, key=lambda s: (seeds[s]["successes"], -s))
    name = f"{algo}_{level}"
    shutil.copyfile(seeds[chosen]["agent"], OUT / f"{name}{RECIPES[algo][2]}")
    write_json(OUT / f"{name}.selection.json",
               {"level": level, "algo": algo, "chosen_seed": chosen,
                "agent": seeds[chosen]["which"], "at_steps": seeds[chosen]["steps"],
                "final_successes_by_seed": {d["record"]["config"]["seed"]:
                                            d["record"]["curve"][-1]["successes"]
                                            for d in done},
                "candidate_successes_by_seed": {s: c["successes"] for s, c in seeds.items()},
                "of": seeds[chosen]["n"],
                "rule": "per seed its best agent (the curve's best point; the final agent "
                        "where the run kept none), then the seed whose candidate scored "
                        "most on the curve's evaluation (8 plants of seed 20061122 under "
                        "the level; for mixed, under each level of the mix, none once on "
                        "the nominal arm)"})
    print(f"{name}: seed {chosen} ({seeds[chosen]['which']} agent at "
          f"{seeds[chosen]['steps']:,} steps, {seeds[chosen]['successes']}/"
          f"{seeds[chosen]['n']}) of {sorted(seeds)}", flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--algos", nargs="+", choices=sorted(RECIPES), default=["ppo"])
    ap.add_argument("--levels", nargs="+", choices=["easy", "medium", "hard", "mixed"],
                    default=["medium", "hard"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3])
    ap.add_argument("--steps", type=float, default=None,
                    help="steps of every run (default per algorithm: PPO 8e5, SAC 3e5, "
                         "IPPO and MAPPO 1.2e6)")
    ap.add_argument("--work", type=Path, default=Path("twolink-results/challenge_agents"))
    args = ap.parse_args(argv)
    OUT.mkdir(parents=True, exist_ok=True)

    def steps(algo: str) -> int:
        return int(args.steps) if args.steps is not None else RECIPES[algo][1]

    for algo in args.algos:
        for seed in args.seeds:                # every level's first seed first
            for level in args.levels:
                run(algo, level, seed, steps(algo), args.work)
        for level in args.levels:
            done = [run(algo, level, s, steps(algo), args.work) for s in args.seeds
                    if _state(args.work / f"{challenge_stem(algo, level)}_seed{s}") == "finished"]
            if done:
                select(algo, level, done)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
