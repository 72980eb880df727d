"""Reinforcement-learning environments: the task core shared by dm_env, Gymnasium and
PettingZoo, and the compensated wrappers.
"""
