"""Reproduction of the paper's Section IV: synthesis, Table II and Fig. 3.
"""
