"""The arm: Table I and the N-link rule, the models (6)-(11), their integration, the
MJCF model, parameter files, and the task's definitions (goal band, rewards (15)/(17),
action levels). The lowest layer: it imports no other subpackage.
"""
