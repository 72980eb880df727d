"""Learned agents for the challenge levels: PPO trained under ``medium`` and ``hard``.

``python docs/studies/challenge_agents.py [--levels medium hard] [--seeds 1 2 3]
[--steps 8e5] [--work DIR]`` runs ``twolink train --algo ppo --challenge LEVEL --history 3
--action-rate 1 --steps N --seed S --eval-every 2e5`` for every level and seed, one run at
a time, each resumed from its last checkpoint when a previous call was interrupted and
skipped when finished. After every finished run it copies the run's ``curve.json`` into
``renders/challenge_agents/<run>.json`` and picks, per level, the seed whose final agent
scored best on the curve's own evaluation (the level on 8 plants of seed 20061122: the
training seeds' side, never the leaderboard's seed 2026), copying that agent to
``renders/challenge_agents/ppo_<level>.zip``, the file the catalogue's ``ppo_<level>``
names. Training seeds 1-3 are neither 2026 nor 20061122 (``twolink train`` refuses
those under a challenge). What each run cost (steps, CPU, wall) is the ``Cost of
learning`` section of the leaderboard (:func:`twolink.control.learned.learning_cost`,
read from the curves copied here).
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

OUT = Path("renders/challenge_agents")
#: The recipe every run shares (the command's options beside level, seed and steps).
RECIPE = ["--algo", "ppo", "--history", "3", "--action-rate", "1", "--eval-every", "200000"]


def _state(folder: Path) -> str:
    try:
        record = json.loads((folder / "curve.json").read_text())
        if record.get("done") and (folder / record["agent"]).is_file():
            return "finished"
    except (OSError, ValueError, KeyError):
        pass
    return "interrupted" if (folder / "checkpoint.pt").is_file() else "new"


def run(level: str, seed: int, steps: int, work: Path) -> dict:
    folder = work / f"ppo_{level}_seed{seed}"
    state = _state(folder)
    if state != "finished":
        cmd = [sys.executable, "-m", "twolink.cli", "train", *RECIPE, "--challenge", level,
               "--seed", str(seed), "--steps", str(steps), "-o", str(folder)]
        if state == "interrupted":
            cmd.append("--resume")
        print(f"{folder.name}: {'resuming' if state == 'interrupted' else 'training'}",
              flush=True)
        subprocess.run(cmd, check=True)
    record = json.loads((folder / "curve.json").read_text())
    write_json(OUT / f"{folder.name}.json", record)
    return {"record": record, "agent": folder / record["agent"]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--levels", nargs="+", default=["medium", "hard"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3])
    ap.add_argument("--steps", type=float, default=8e5)
    ap.add_argument("--work", type=Path, default=Path("twolink-results/challenge_agents"))
    args = ap.parse_args(argv)
    OUT.mkdir(parents=True, exist_ok=True)
    for seed in args.seeds:                    # every level's first seed first
        for level in args.levels:
            run(level, seed, int(args.steps), args.work)
    for level in args.levels:
        done = [run(level, s, int(args.steps), args.work) for s in args.seeds
                if _state(args.work / f"ppo_{level}_seed{s}") == "finished"]
        if not done:
            continue
        best = max(done, key=lambda d: (d["record"]["curve"][-1]["successes"],
                                        -d["record"]["config"]["seed"]))
        shutil.copyfile(best["agent"], OUT / f"ppo_{level}.zip")
        picks = {d["record"]["config"]["seed"]: d["record"]["curve"][-1]["successes"]
                 for d in done}
        write_json(OUT / f"ppo_{level}.selection.json",
                   {"level": level, "chosen_seed": best["record"]["config"]["seed"],
                    "final_successes_by_seed": picks,
                    "of": best["record"]["curve"][-1]["n"],
                    "rule": "the seed whose final agent scored most on the curve's "
                            "evaluation (8 plants of seed 20061122 under the level)"})
        print(f"ppo_{level}: seed {best['record']['config']['seed']} of {sorted(picks)} "
              f"({picks})", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
