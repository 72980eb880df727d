"""Controllers: synthesis of the centralized (16) and decentralized (18) policies by
Alg. 1, N-link agents, and online learning.
"""
