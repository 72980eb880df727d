"""The subcommands of ``twolink``: one module each, defining ``add_parser(subparsers)``
(returning its parser) and ``run(args) -> int``; they parse, call and print."""

#: Every subcommand with its one-line summary, in the order ``twolink --help`` lists them.
SUMMARIES = {
    "reproduce": "reproduce the paper's experiment (the main job)",
    "synthesize": "synthesise a policy with fuzzy Q-iteration (Alg. 1)",
    "mjcf": "write the MJCF model generated from Table I",
    "rollout": "run policies on plants; summary, trajectories, Fig. 3",
    "render": "render videos of the arm offscreen (EGL), MP4 or GIF",
    "mismatch": "model mismatch, its closure and robustness sweeps",
    "learn": "online fuzzy Q-learning on the MuJoCo arm (many arms, one theta)",
    "train": "deep RL (PPO, SAC; IPPO, MAPPO) on N links; exact resume; the agent is a controller",
    "identify": "identify P1, P2, P3, b1, b2 from a logged MuJoCo experiment",
    "controllers": "list the controller catalogue: every named controller, by tag",
    "evaluate": "score one controller (yours too) under a challenge level on MuJoCo",
    "leaderboard": "every controller under every challenge level, against the time-optimal limit",
    "scaling": "Table II extended to N links: memory, time and success of both schemes",
    "learners": "Table II for today's learners: PPO, IPPO, MAPPO on N links (resumable study)",
    "limits": "the time-optimal limit T*(x) of the arm (CasADi/IPOPT; shipped table)",
}
