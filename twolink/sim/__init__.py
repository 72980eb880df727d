"""Simulation and measurement: plants (MuJoCo and the numpy models), perturbations and
challenges, state estimation, identification, closed-loop rollouts, metrics and the one
evaluation of a controller.
"""
