#!/usr/bin/env bash
# Regenerate the committed results, on purpose (`make results`): every command runs with
# TWOLINK_OUTPUT=renders, so its default folder is the checkout's tracked renders/ (the
# commands' ordinary default, ./twolink-results/, is ignored by git), then
# `python docs/generate.py` rewrites the README blocks and docs pages from the new data.
#
#   scripts/results.sh [VENV] [STEP...]     steps (default: all, in this order):
#     reproduce        twolink reproduce --report docs/data/reproduce.json (renders/fig3.png)
#     leaderboard      twolink leaderboard --all       (renders/leaderboard/, about an hour)
#     leaderboard-md   twolink leaderboard --from-json renders/leaderboard/leaderboard.json
#                      (the Markdown and figure again, nothing measured)
#     scaling          twolink scaling --poses 256     (renders/scaling/)
#     mismatch         twolink mismatch                (renders/mismatch/)
#     mismatch-3link   twolink mismatch --links 3      (renders/mismatch-3link/)
#     docs             python docs/generate.py
#
# The development studies' data (renders/fuzzy_design/, grid_study/, ...) come from the
# scripts of docs/studies/ with their --json paths (docs/studies/README.md).
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${1:-.venv}
shift || true
PY="$VENV/bin/python"
TWOLINK="$VENV/bin/twolink"
export TWOLINK_OUTPUT=renders
ALL=(reproduce leaderboard scaling mismatch mismatch-3link docs)
if [ $# -eq 0 ]; then STEPS=("${ALL[@]}"); else STEPS=("$@"); fi
for step in "${STEPS[@]}"; do
    echo "== results: $step" >&2
    case "$step" in
        reproduce)      "$TWOLINK" reproduce --report docs/data/reproduce.json ;;
        leaderboard)    "$TWOLINK" leaderboard --all --out renders/leaderboard ;;
        leaderboard-md) "$TWOLINK" leaderboard --from-json renders/leaderboard/leaderboard.json ;;
        scaling)        "$TWOLINK" scaling --poses 256 --out renders/scaling ;;
        mismatch)       "$TWOLINK" mismatch --out renders/mismatch ;;
        mismatch-3link) "$TWOLINK" mismatch --links 3 --out renders/mismatch-3link ;;
        docs)           "$PY" docs/generate.py ;;
        *) echo "results: unknown step '$step'; the steps are ${ALL[*]} leaderboard-md" >&2
           exit 2 ;;
    esac
done
