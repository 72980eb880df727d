"""Deep RL on the MuJoCo arm: a thin caller of ``twolink train``.

``python docs/studies/deep_rl.py ARGS`` runs ``twolink train ARGS``
(:mod:`twolink.commands.train`, :mod:`twolink.training`): SB3's PPO or SAC with one
hyperparameter set on :class:`twolink.envs.sb3.TwoLinkSB3VecEnv`, the deterministic
policy scored on the paper's metric every ``--eval-every`` steps, the learning curve and
exact-resume checkpoints in ``--out DIR``, the final agent saved as a controller. See
docs/guides/training.md. The curves committed under ``renders/deep_rl/`` were written by
this script's earlier form (with a ``--minutes`` wall-clock budget).

Needs the rl extras: ``bash scripts/install-rl-extras.sh .venv``.
"""
from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from twolink.cli import main as twolink_main  # noqa: E402


def main(argv=None) -> int:
    """``twolink train`` with ``argv`` (default: this script's arguments)."""
    return twolink_main(["train", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    sys.exit(main())
