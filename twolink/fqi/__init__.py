"""Fuzzy Q-iteration: the fuzzy partition (12)-(14) and the sweeps of Alg. 1 (fixed-width
and factored transition tables; their compiled kernels are private). Imports only
:mod:`twolink.arm`.
"""
