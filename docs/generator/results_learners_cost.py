"""The learners page's cost targets: training cost (the cheapest six-link study row and
lever run that learnt, CPU per step over the whole run, beside the training benchmark's
default, lighter and on-the-model recipes measured in one run, ``benchmarks/training.py``)
and the study's duration (each complete seed's wall time, and the CPU its runs used
against what two cores give in the target's time)."""
from __future__ import annotations

from .common import SCHEMAS, _load

#: Training cost target at N = 6: CPU microseconds per environment step.
COST_TARGET_US = 150.0
#: Study duration targets on this 2-core machine: the full study and one seed, hours.
STUDY_HOURS, SEED_HOURS = 8.0, 2.0
#: Cores of the machine the duration targets are set for.
CORES = 2
#: The training benchmark's data, and per algorithm the stem of the lever runs of its
#: lighter recipe (one per seed).
BENCH = "benchmarks/results.json"
LIGHT_LEVERS = {"PPO": "ppo-pd-light_6t_seed", "MAPPO": "mappo-neighbours-cheap12m_6t_seed"}


def cost_target(rows: list) -> str:
    """The target's line: met when the cheapest six-link study row or lever run that
    learnt costs at most :data:`COST_TARGET_US` per step."""
    from twolink.viz.formatting import format_rate

    six = [r for r in rows if r["links"] == 6]
    if not six:
        return (f"- not yet run: training cost at N = 6 <= {COST_TARGET_US:.0f} µs CPU "
                "per environment step")
    cheapest = min(six, key=lambda r: r["cpu_us_per_step"])
    lever = min(_lever_costs(), key=lambda c: c[1], default=None)
    cost = min([cheapest["cpu_us_per_step"]] + ([] if lever is None else [lever[1]]))
    met = cost <= COST_TARGET_US
    learnt = ("" if lever is None else
              f"; cheapest six-link lever run that learnt (below): `{lever[0]}` "
              f"{lever[1]:.0f} µs, its fresh poses at 8 s "
              f"{format_rate(lever[2]['successes'], lever[2]['n'])}")
    return (f"- {'met' if met else '**missed**'}: training cost at N = 6 <= "
            f"{COST_TARGET_US:.0f} µs CPU per environment step (updates and the "
            f"curve's evaluations included): cheapest {cheapest['learner']} "
            f"{cheapest['cpu_us_per_step']:.0f} µs" + learnt + _light_cost() + _model_cost())


def _lever_costs() -> list:
    """(run, CPU microseconds per step over the whole run, fresh score at 8 s) of every
    finished six-link lever run whose final agent settles some of the fresh poses (a run
    that learnt nothing meets no cost target)."""
    from .results_learners import scored_levers

    return [(stem, 1e6 * record["cpu_s"] / record["steps"], fresh)
            for stem, record, fresh in scored_levers()
            if record["config"]["links"] == 6 and record.get("done")
            and fresh["successes"] > 0]


def _model_cost() -> str:
    """The training benchmark's MAPPO rows on the model (6) (``benchmarks/training.py``'s
    ``MODEL_RECIPE``): training on the model, the same recipe on MuJoCo and the model's
    physics alone, measured in one run; empty without them."""
    bench = _load(BENCH, SCHEMAS[BENCH])
    found = {r["name"]: r for r in (bench or {}).get("rows", [])
             if r["section"].startswith("training: MAPPO, 6 links, on the model (6)")}
    keys = ("training on the model, updates included: CPU per env step",
            "the same recipe on MuJoCo: CPU per env step",
            "physics alone (the model): CPU per env step")
    if not all(k in found for k in keys):
        return ""
    model, mujoco, physics = (found[k]["value"] for k in keys)
    recipe = found[keys[0]]["section"].split("on the model (6) ")[-1]
    return (f"; MAPPO trained on the model (6) {recipe} {model:.0f} µs "
            f"({'meets' if model <= COST_TARGET_US else 'misses'} the target; "
            f"{model / physics:.1f} × the model's physics alone, {physics:.0f} µs), the "
            f"same recipe on MuJoCo {mujoco:.0f} µs")


def _light_cost() -> str:
    """The training benchmark's lighter recipes at six links (updates included, no
    evaluations) beside the default ones and the physics alone, measured in one run, and
    how their lever runs learnt."""
    import json

    from twolink.viz.formatting import format_rate

    from . import common
    from .results_learners import LEVERS

    bench = _load(BENCH, SCHEMAS[BENCH])
    found, physics = {}, None
    for r in (bench or {}).get("rows", []):
        sec = r["section"]
        if r["name"].startswith("physics alone") and sec.startswith("training: PPO, 6 links"):
            physics = r["value"]
        for algo in LIGHT_LEVERS:
            if sec.startswith(f"training: {algo}, 6 links") and r["name"].startswith(
                    "training, updates included"):
                found[algo, "light" if "lighter recipe" in sec else "default"] = r
    parts = []
    for algo, stem in LIGHT_LEVERS.items():
        if (algo, "light") not in found or (algo, "default") not in found:
            continue
        light, default = found[algo, "light"]["value"], found[algo, "default"]["value"]
        scored = sorted((common.ROOT / LEVERS).glob(f"{stem}*.fresh.json"))
        learnt = ""
        if scored:
            runs = ", ".join(
                f"`{p.name[:-len('.fresh.json')]}` {format_rate(f['successes'], f['n'])}"
                for p, f in ((p, json.loads(p.read_text())) for p in scored))
            learnt = f"; its runs (below) on the fresh poses: {runs}"
        recipe = found[algo, "light"]["section"].split("lighter recipe ")[-1]
        met = light <= COST_TARGET_US
        parts.append(f"the default {algo} recipe {default:.0f} µs, the lighter recipe "
                     f"{recipe} {light:.0f} µs ({'meets' if met else 'misses'} the "
                     f"target){learnt}")
    if not parts:
        return ""
    floor = "" if physics is None else f"; the physics alone {physics:.0f} µs"
    return (". The training benchmark (updates included, no evaluations; one run"
            f"{floor}): " + "; ".join(parts))


def study_time(data: dict) -> str:
    """The duration targets' line against the committed runs: each complete seed's wall
    time (its runs' walls added up), the whole plan at that pace, and the cause when
    missed: the CPU a seed's training used against the :data:`CORES` cores'
    ``CORES x SEED_HOURS`` CPU hours, for every learner of the plan and for the issue's
    five (no PD base, trained on MuJoCo), and the average CPU per environment step that
    would fit one seed's steps in that budget beside the one measured."""
    from twolink.studies.learners.plan import plan

    planned = plan()
    per_seed = {}
    for p in planned:
        per_seed.setdefault(p.seed, []).append(p)
    done = {r["id"]: r for r in data["runs"]}
    complete = {seed: [done[p.id] for p in runs] for seed, runs in per_seed.items()
                if all(p.id in done for p in runs)}
    what = (f"the full study <= {STUDY_HOURS:g} h on this {CORES}-core machine, one seed "
            f"<= {SEED_HOURS:g} h")
    if not complete:
        return f"- not yet measured: {what} (no seed is complete)"
    wall = {s: sum(r["wall_s"] for r in rs) / 3600 for s, rs in complete.items()}
    whole = sum(wall.values()) / len(wall) * len(per_seed)
    seed, runs = max(complete.items(), key=lambda kv: wall[kv[0]])
    cpu = sum(r["cpu_s"] for r in runs) / 3600
    five = {p.id for p in per_seed[seed] if p.base == "none" and p.plant == "mujoco"}
    cpu5 = sum(r["cpu_s"] for r in runs if r["id"] in five) / 3600
    steps = sum(r["steps"] for r in runs)
    budget = CORES * SEED_HOURS
    fits = 3600e6 * budget / steps
    cheapest = min(((r["id"], 1e6 * r["cpu_s"] / r["steps"]) for r in data["runs"]),
                   key=lambda c: c[1])
    met = max(wall.values()) <= SEED_HOURS and whole <= STUDY_HOURS
    line = (f"- {'met' if met else '**missed**'}: {what}: a complete seed's runs took "
            + ", ".join(f"{h:.1f} h (seed {s})" for s, h in sorted(wall.items()))
            + f" of wall time added up, so the {len(planned)} runs take about {whole:.0f} h "
            "at that pace")
    if met:
        return line
    return line + (
        f". Cause: the CPU. Seed {seed}'s training used {cpu:.1f} CPU hours "
        f"({cpu5:.1f} for the issue's {len(five)} runs without the PD base or the model); "
        f"{CORES} cores give {budget:g} CPU hours in {SEED_HOURS:g} h, so with both busy "
        f"throughout the seed takes at least {cpu / CORES:.1f} h ({cpu5 / CORES:.1f} h). "
        f"Its {steps / 1e6:.1f} M environment steps cost {1e6 * 3600 * cpu / steps:.0f} µs "
        f"each on average, curve evaluations included; one seed in {SEED_HOURS:g} h asks "
        f"for {fits:.0f} µs, " + (
            f"less than the cheapest run of the study costs ({cheapest[1]:.0f} µs, "
            f"`{cheapest[0]}`)" if fits < cheapest[1] else
            f"which the cheapest run of the study reaches ({cheapest[1]:.0f} µs, "
            f"`{cheapest[0]}`)"))
