#!/usr/bin/env bash
# Usage: scripts/ci-wheel-smoke.sh [PYTHON]   (default python3)
# Installs twolink NON-editable (`pip install .` of a clean copy of the checkout's files)
# into a fresh virtual environment and runs the commands from a folder outside the
# checkout, checking that outputs land where the README says: ./twolink-results/ under the
# working directory by default, $TWOLINK_OUTPUT when set, an explicit -o as given.
set -euo pipefail
python=${1:-python3}
root=$(cd "$(dirname "$0")/.." && pwd)
tmp=$(mktemp -d "${TMPDIR:-/tmp}/twolink-wheel.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
unset TWOLINK_OUTPUT MUJOCO_GL PYOPENGL_PLATFORM PYTHONPATH

fail() { echo "wheel smoke: FAILED: $*" >&2; exit 1; }
step() { label=$1; }
took() { printf 'wheel smoke: %-58s ok (%d s)\n' "$label" $((SECONDS - t0)) >&2; }
files() { (cd "$1" 2>/dev/null && find . -type f | sort) || true; }

# The files a commit would hold (tracked and untracked-but-not-ignored), not a build/
# left by an earlier build.
step "copy the checkout"; t0=$SECONDS
mkdir "$tmp/src"
if git -C "$root" rev-parse --git-dir > /dev/null 2>&1; then
  (cd "$root" && git ls-files -z --cached --others --exclude-standard \
    | while IFS= read -r -d '' f; do [ ! -e "$f" ] || printf '%s\0' "$f"; done \
    | tar --null -cf - -T -) | tar -xf - -C "$tmp/src"
else
  tar -C "$root" --exclude=./.venv --exclude=./build --exclude='*.egg-info' -cf - . \
    | tar -xf - -C "$tmp/src"
fi
took

step "fresh venv ($("$python" -c 'import platform; print(platform.python_version())'))"
t0=$SECONDS
"$python" -m venv "$tmp/venv"
"$tmp/venv/bin/python" -m pip install -q --upgrade pip
took
step "pip install . (non-editable)"; t0=$SECONDS
(cd "$tmp/src" && "$tmp/venv/bin/python" -m pip install -q .)
took
bin="$tmp/venv/bin"
work="$tmp/work"
mkdir "$work"
cd "$work"

step "installed copy is not the checkout"; t0=$SECONDS
where=$("$bin/python" -c 'import twolink; print(twolink.__file__)')
case "$where" in "$tmp/venv/"*) ;; *) fail "twolink imported from $where" ;; esac
shipped=$("$bin/python" -c 'from twolink.resources import shipped_policy_dir as d; print(d())')
before=$(files "$shipped")
took

step "twolink --version"; t0=$SECONDS
want=$("$bin/python" -c 'import importlib.metadata as m; print("twolink", m.version("twolink"))')
[ "$("$bin/twolink" --version)" = "$want" ] || fail "twolink --version is not '$want'"
took

step "load_policy('decentralized')"; t0=$SECONDS
"$bin/python" -c 'from twolink.policy import load_policy; load_policy("decentralized")'
took

step "twolink reproduce -> ./twolink-results/fig3.png"; t0=$SECONDS
"$bin/twolink" reproduce > reproduce.txt || fail "twolink reproduce: $(tail -3 reproduce.txt)"
[ -s twolink-results/fig3.png ] || fail "twolink reproduce wrote no ./twolink-results/fig3.png"
[ "$(ls -A | tr '\n' ' ')" = "reproduce.txt twolink-results " ] || fail "twolink reproduce wrote $(ls -A)"
took

step "twolink rollout --no-save writes nothing"; t0=$SECONDS
listing=$(files .)
"$bin/twolink" rollout --no-save > /dev/null
[ "$(files .)" = "$listing" ] || fail "twolink rollout --no-save wrote $(comm -13 <(echo "$listing") <(files .))"
took

step "twolink rollout -> ./twolink-results/rollout.*"; t0=$SECONDS
"$bin/twolink" rollout > /dev/null
for ext in csv npz; do [ -s "twolink-results/rollout.$ext" ] || fail "no ./twolink-results/rollout.$ext"; done
took

step "TWOLINK_OUTPUT=out twolink rollout -> out/rollout.*"; t0=$SECONDS
TWOLINK_OUTPUT="$tmp/out" "$bin/twolink" rollout > /dev/null
for ext in csv npz; do [ -s "$tmp/out/rollout.$ext" ] || fail "no \$TWOLINK_OUTPUT/rollout.$ext"; done
took

step "twolink render -o x.mp4 (headless EGL)"; t0=$SECONDS
"$bin/twolink" render --no-progress --duration 0.2 --size 160x120 -o x.mp4 > /dev/null
[ -s x.mp4 ] || fail "twolink render wrote no ./x.mp4"
took

step "twolink render -> ./twolink-results/centralized_mujoco.mp4"; t0=$SECONDS
"$bin/twolink" render --no-progress --duration 0.2 --size 160x120 > /dev/null
[ -s twolink-results/centralized_mujoco.mp4 ] || fail "no ./twolink-results/centralized_mujoco.mp4"
took

step "twolink synthesize decentralized -o d.npz"; t0=$SECONDS
"$bin/twolink" synthesize decentralized -o d.npz > /dev/null
[ -s d.npz ] || fail "twolink synthesize wrote no ./d.npz"
"$bin/python" -c 'from twolink.policy import load_policy; load_policy("d.npz")'
took

step "the installed package is left unchanged"; t0=$SECONDS
[ "$(files "$shipped")" = "$before" ] || fail "files under $shipped changed"
took

if ! "$bin/python" -c 'import dm_control' 2>/dev/null; then
  # Python >= 3.13: labmaze, a dependency of dm-control, has no wheel (pyproject.toml).
  step "pip install --no-deps dm-control"; t0=$SECONDS
  pin=$("$bin/python" -c 'import importlib.metadata as m; print(next(r.split(";")[0].strip() for r in m.requires("twolink") if r.startswith("dm-control")))')
  "$bin/python" -m pip install -q --no-deps "$pin"
  took
fi
step "twolink.envs.dm: load, step, render"; t0=$SECONDS
"$bin/python" - <<'EOF'
import twolink.envs.dm
env = twolink.envs.dm.load("centralized")
env.reset()
env.step([0.0, 0.0])
assert env.physics.render(height=48, width=64, camera_id="top").std() > 10
EOF
took

step "Gymnasium and PettingZoo: make, step, render, checker"; t0=$SECONDS
"$bin/python" - <<'EOF'
import gymnasium
from gymnasium.utils.env_checker import check_env
import twolink.envs.gym
from twolink.envs import pettingzoo as twolink_pz
env = gymnasium.make("twolink/TwoLink-v0", render_mode="rgb_array")
check_env(env.unwrapped, skip_render_check=True)
env.reset(seed=0)
env.step(env.action_space.sample())
assert env.render().std() > 10
env.close()
envs = gymnasium.make_vec("twolink/TwoLink-v0", num_envs=4)
envs.reset(seed=0)
envs.step(envs.action_space.sample())
envs.close()
pz = twolink_pz.parallel_env()
obs, _ = pz.reset(seed=0)
obs, rewards, *_ = pz.step({a: pz.action_space(a).sample() for a in pz.agents})
assert set(rewards) == {"link1", "link2"}
pz.close()
EOF
took
echo "wheel smoke: all checks passed" >&2
