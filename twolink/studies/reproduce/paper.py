"""The figures the paper reports (Section IV-C, Table II, Fig. 3), for side-by-side tables.

These are the paper's numbers, quoted for comparison; nothing of ours is computed here.
"""

#: Value-iteration sweeps to convergence (Section IV-C).
ITERATIONS = {"centralized": 125, "agent1": 192, "agent2": 49}
#: Q-table sizes (Table II).
Q_SIZES = {"centralized": 63504, "agent1": 9072, "agent2": 252}
#: CPU seconds (Table II; Matlab 7.1, Centrino Duo 1.83 GHz). Agent 1's and agent 2's
#: entries are almost certainly swapped in the paper: agent 2's table is 36x smaller.
CPU_SECONDS = {"centralized": 18300.0, "agent1": 1.7, "agent2": 1000.0, "decentralized": 1000.0}
#: Both policies stabilise the simplified system from x0 in about 1.2 s (Fig. 3).
SETTLE_TIME = {"centralized": 1.2, "decentralized": 1.2}
#: Steady-state angle offsets lie inside the 5 degree band.
OFFSET_BOUND_DEG = 5.0
