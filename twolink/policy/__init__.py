"""Policies (14): the greedy read-out of a fuzzy Q-table, the policy file format, and
the registry of shipped policies.
"""
from twolink.policy.fuzzy_policy import (
                                         Agent,
                                         Policy,
                                         PolicyFileError,
                                         greedy_indices,
                                         load_policy,
                                         shipped_policies,
)

__all__ = ["Agent", "Policy", "PolicyFileError", "greedy_indices", "load_policy",
           "shipped_policies"]
