"""Saved SB3 agents are data, never code: a crafted pickle in a save's ``data`` never runs
(through resolve_controller or ``twolink evaluate``), a member that inflates past the cap
is refused before it is read, no command loads a folder's ``*.zip`` unnamed, and the
shipped ``ppo_seed0`` resolves by name with the torques of ``PPO.load``. Skipped where
SB3 is not installed."""
from __future__ import annotations

import base64
import json
import os
import pickle
import resource
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

sb3 = pytest.importorskip("stable_baselines3")

from twolink.arm.parameters import TABLE_I  # noqa: E402
from twolink.control.controllers import resolve_controller  # noqa: E402
from twolink.control.learned import LEARNED_AGENTS, learned_agent_path  # noqa: E402
from twolink.control.sb3_agent import MAX_BYTES, model_torques  # noqa: E402
from twolink.sim.controller import ControllerError  # noqa: E402
from twolink.sim.metrics import evaluation_set  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


class _Touch:
    """Unpickling it runs ``touch MARKER`` (the attack a save's data can carry)."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (os.system, (f"touch '{self.marker}'",))


def _payload(marker) -> dict:
    return {":type:": "<class 'dict'>",
            ":serialized:": base64.b64encode(pickle.dumps(_Touch(marker))).decode()}


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """An untrained, seeded PPO (net_arch [16], ReLU) on the training environment's
    options, saved; (model, path)."""
    import torch

    from twolink.envs.sb3 import TwoLinkSB3VecEnv

    torch.set_num_threads(1)
    env = TwoLinkSB3VecEnv(2, observation="cos_sin", actions="normalized", reward="shaped",
                           x0="random")
    model = sb3.PPO("MlpPolicy", env, seed=3, device="cpu", n_steps=8, batch_size=16,
                    policy_kwargs={"net_arch": [16], "activation_fn": torch.nn.ReLU})
    path = tmp_path_factory.mktemp("agents") / "tiny_ppo.zip"
    model.save(path)
    env.close()
    return model, path


def _rewrite(src: Path, dst: Path, change) -> Path:
    """A copy of the save ``src`` at ``dst`` whose data is ``change(data)``."""
    with zipfile.ZipFile(src) as z, zipfile.ZipFile(dst, "w") as out:
        for info in z.infolist():
            raw = z.read(info)
            if info.filename == "data":
                data = json.loads(raw)
                change(data)
                raw = json.dumps(data).encode()
            out.writestr(info.filename, raw)
    return dst


def _crafted(tiny, tmp_path, marker):
    """Three crafted saves: an extra pickled key; observation_space's blob replaced
    (readable fields kept); policy_kwargs replaced by a blob alone (no readable copy)."""
    def extra(d):
        d["evil"] = _payload(marker)

    def space(d):
        d["observation_space"][":serialized:"] = _payload(marker)[":serialized:"]
        d["action_space"][":serialized:"] = _payload(marker)[":serialized:"]
        d["policy_class"][":serialized:"] = _payload(marker)[":serialized:"]

    def kwargs(d):
        d["policy_kwargs"] = _payload(marker)

    return [_rewrite(tiny[1], tmp_path / f"{name}.zip", f)
            for name, f in (("extra", extra), ("space", space), ("kwargs", kwargs))]


def test_the_payload_would_run_if_unpickled(tiny, tmp_path):
    """The crafted data is a real attack: SB3's own reader of ``data`` runs it."""
    from stable_baselines3.common.save_util import json_to_data

    marker = tmp_path / "ran"
    extra = _crafted(tiny, tmp_path, marker)[0]
    with zipfile.ZipFile(extra) as z:
        json_to_data(z.read("data").decode())
    assert marker.exists()


def test_a_crafted_save_runs_nothing(tiny, tmp_path):
    marker = tmp_path / "MARKER"
    extra, space, kwargs = _crafted(tiny, tmp_path, marker)
    x = evaluation_set()[:10]
    want = model_torques(tiny[0], x, "cos_sin", TABLE_I.tau_max)
    for path in (extra, space):          # the readable fields are intact: a correct load
        agent = resolve_controller(str(path))
        np.testing.assert_allclose(agent(x), want, rtol=0, atol=1e-12)
    # With no readable policy_kwargs the defaults (64, 64) do not fit the weights: one line.
    with pytest.raises(ControllerError) as e:
        resolve_controller(str(kwargs))
    assert "policy.pth does not fit the policy its data describes" in str(e.value)
    assert "mlp_extractor.policy_net.0.weight (16, 6) not (64, 6)" in str(e.value)
    assert "\n" not in str(e.value)
    assert not marker.exists()


def test_the_cli_runs_nothing_of_a_crafted_save(tiny, tmp_path):
    marker = tmp_path / "MARKER"
    extra, _, kwargs = _crafted(tiny, tmp_path, marker)
    env = {**os.environ, "TWOLINK_OUTPUT": str(tmp_path / "out")}
    cmd = [sys.executable, "-m", "twolink.cli", "evaluate", "--quick", "--json"]
    ok = subprocess.run([*cmd, str(extra)], capture_output=True, text=True, env=env,
                        cwd=tmp_path, timeout=300)
    assert ok.returncode == 0, ok.stderr
    result = json.loads(ok.stdout)
    assert result["n"] == 5
    bad = subprocess.run([*cmd, str(kwargs)], capture_output=True, text=True, env=env,
                         cwd=tmp_path, timeout=300)
    assert bad.returncode == 2 and bad.stdout == ""
    lines = bad.stderr.strip().splitlines()
    assert len(lines) == 1 and "policy.pth does not fit" in lines[0]
    assert not marker.exists()


def _rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def test_a_zip_bomb_is_refused_before_it_is_read(tiny, tmp_path):
    # data: 200 MiB of zeros deflated to ~200 kB, written in chunks.
    bomb = tmp_path / "bomb.zip"
    with zipfile.ZipFile(tiny[1]) as z, zipfile.ZipFile(bomb, "w", zipfile.ZIP_DEFLATED) as out:
        out.writestr("policy.pth", z.read("policy.pth"))
        with out.open("data", "w") as f:
            chunk = b"\0" * 2**20
            for _ in range(200):
                f.write(chunk)
    assert bomb.stat().st_size < 2**20
    rss, t = _rss_mib(), time.perf_counter()
    with pytest.raises(ControllerError) as e:
        resolve_controller(str(bomb))
    assert str(e.value) == (f"{bomb}: member 'data' inflates to {200 * 2**20:,} bytes, more "
                            f"than the {MAX_BYTES:,} a saved agent may hold")
    assert time.perf_counter() - t < 5
    assert _rss_mib() - rss < 100


def test_a_member_lying_about_its_size_is_read_no_further(tiny, tmp_path):
    """A member that declares a small size but inflates to more is cut at the declared
    size, so its CRC fails: one line, never more than the declared bytes read."""
    liar = tmp_path / "liar.zip"
    with zipfile.ZipFile(tiny[1]) as z, zipfile.ZipFile(liar, "w", zipfile.ZIP_DEFLATED) as out:
        out.writestr("policy.pth", z.read("policy.pth"))
        out.writestr("data", b" " * (64 * 2**20) + b"{}")
    raw = bytearray(liar.read_bytes())
    declared = (64 * 2**20 + 2).to_bytes(4, "little")
    small = (1000).to_bytes(4, "little")
    assert raw.count(declared) == 2          # the local header and the central directory
    liar.write_bytes(bytes(raw).replace(declared, small))
    with pytest.raises(ControllerError) as e:
        resolve_controller(str(liar))
    assert str(e.value).startswith(f"{liar}: member 'data' cannot be read: Bad CRC-32")


def test_the_default_leaderboard_loads_no_zip_of_the_working_folder(tiny, tmp_path,
                                                                       monkeypatch):
    from twolink.commands.leaderboard import chosen_specs, controllers_of

    marker = tmp_path / "MARKER"
    (tmp_path / "renders" / "deep_rl").mkdir(parents=True)
    crafted = _crafted(tiny, tmp_path, marker)[0]
    for where in (tmp_path / "renders" / "deep_rl", tmp_path / "out" / "deep_rl"):
        where.mkdir(parents=True, exist_ok=True)
        (where / "evil.zip").write_bytes(crafted.read_bytes())
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("TWOLINK_OUTPUT", raising=False)
    specs = chosen_specs(None, [])
    assert not any(s.endswith(".zip") for s in specs)
    assert "lqr" in specs and "ppo_medium" in specs         # the shipped, named agents
    assert "ppo_seed0" not in specs                         # nominal only: in --all
    monkeypatch.setenv("TWOLINK_OUTPUT", str(tmp_path / "out"))
    assert chosen_specs(None, []) == specs
    controllers = controllers_of(None, [])
    assert "evil" not in controllers and "ppo_hard" in controllers
    assert not marker.exists()
    # A named agent's file given as a path is not run twice.
    committed = str(ROOT / LEARNED_AGENTS["ppo_hard"])
    again = chosen_specs(None, [committed])
    assert "ppo_hard" not in again and again[-1] == committed
    assert "ppo_seed0" in chosen_specs(None, [], every=True)


def test_ppo_seed0_resolves_by_name_with_the_torques_of_ppo_load():
    path = learned_agent_path("ppo_seed0")
    assert path == ROOT / "renders" / "deep_rl" / "ppo_seed0.zip"
    agent = resolve_controller("ppo_seed0")
    assert agent.name == "ppo_seed0" and agent.meta["algo"] == "ppo"
    assert (agent.meta["seed"], agent.meta["steps"]) == (0, 198672)
    x = evaluation_set()
    trusted = sb3.PPO.load(path, device="cpu")      # the committed file: trusted here
    want = model_torques(trusted, x, "cos_sin", TABLE_I.tau_max)
    u = agent(x)
    np.testing.assert_allclose(u, want, rtol=0, atol=1e-6)
    assert np.ptp(u, axis=0).min() > 0


def test_a_learned_agent_outside_a_checkout_is_one_line(monkeypatch):
    import twolink.resources

    monkeypatch.setattr(twolink.resources, "source_checkout", lambda: None)
    with pytest.raises(ControllerError) as e:
        resolve_controller("ppo_seed0")
    assert str(e.value) == ("learned agent ppo_seed0 is the file renders/deep_rl/ppo_seed0.zip "
                            "of a source checkout of the repository, and this one has none")
    from twolink.commands.leaderboard import chosen_specs

    assert not {"ppo_seed0", "ppo_medium"} & set(chosen_specs(None, [], every=True))


def test_a_sac_save_loads_with_the_torques_of_sac_load(tmp_path):
    import torch

    from twolink.envs.sb3 import TwoLinkSB3VecEnv

    torch.set_num_threads(1)
    env = TwoLinkSB3VecEnv(2, observation="state", actions="normalized", reward="shaped",
                           x0="random")
    model = sb3.SAC("MlpPolicy", env, seed=5, device="cpu", buffer_size=64,
                    policy_kwargs={"net_arch": {"pi": [12], "qf": [8]}})
    path = tmp_path / "tiny_sac.zip"
    model.save(path)
    env.close()
    agent = resolve_controller(str(path))
    x = evaluation_set()[:20]
    assert agent.meta["algo"] == "sac" and agent.meta["observation"] == "state"
    np.testing.assert_allclose(agent(x), model_torques(model, x, "state", TABLE_I.tau_max),
                               rtol=0, atol=1e-12)


@pytest.mark.parametrize("change, message", [
    (lambda d: d["policy_kwargs"].update(activation_fn="<class 'os.system'>"),
     "its activation function <class 'os.system'> is none of torch.nn's"),
    (lambda d: d["policy_kwargs"].update(features_extractor_class="<class 'x.Evil'>"),
     "its policy_kwargs set 'features_extractor_class', which this loader does not rebuild"),
    (lambda d: d["policy_kwargs"].update(net_arch=[100000, 100000]),
     "weights, more than a policy.pth of"),
    (lambda d: d["action_space"].update(high="[2. 2.]"),
     "the agent's actions are a Box of shape (2,) from [-1.0, -1.0] to [2.0, 2.0]"),
    (lambda d: d["policy_class"].update(__init__="<function ActorCriticCnnPolicy.__init__ at "
                                                 "0x1>"),
     "its policy is ActorCriticCnnPolicy; the loader rebuilds PPO's MlpPolicy"),
])
def test_unreadable_fields_are_one_line(tiny, tmp_path, change, message):
    def fix(d):
        d["policy_kwargs"] = {"net_arch": [16],
                              "activation_fn": "<class 'torch.nn.modules.activation.ReLU'>"}
        change(d)

    path = _rewrite(tiny[1], tmp_path / "bad.zip", fix)
    with pytest.raises(ControllerError) as e:
        resolve_controller(str(path))
    assert message in str(e.value) and "\n" not in str(e.value)


def test_weights_that_are_not_plain_tensors_are_one_line(tiny, tmp_path):
    marker = tmp_path / "MARKER"
    path = tmp_path / "pickled_weights.zip"
    with zipfile.ZipFile(tiny[1]) as z, zipfile.ZipFile(path, "w") as out:
        out.writestr("data", z.read("data"))
        out.writestr("policy.pth", pickle.dumps(_Touch(marker)))
    with pytest.raises(ControllerError) as e:
        resolve_controller(str(path))
    assert "its policy.pth is no weights-only torch file" in str(e.value)
    assert "\n" not in str(e.value)
    assert not marker.exists()
