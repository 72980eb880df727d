"""Today's deep learners on N-link arms (centralized PPO, IPPO, MAPPO), the study of
``twolink learners``: its plan, its resumable measurement and its report.
"""
