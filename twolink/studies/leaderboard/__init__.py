"""The leaderboard: every controller (shipped fuzzy policies, classical baselines, a
user's own) under every challenge level, plain and compensated, against the time-optimal
limit; measured in :mod:`.measure`, presented in :mod:`.report`.
"""
