"""The tuning study of the fuzzy designs: every lever of the tuned designs (torque
levels, bins, read-out, robust models, refinement, agent 2's view of joint 1) and the
study-only controllers the package does not ship, each measured on the tuning seeds
(:data:`twolink.policy.registry.TUNING_SEEDS`) only.

The states and plants are in :mod:`.tuning_set`, the study-only controllers in
:mod:`.designs` (synthesised) and :mod:`.wrappers` (around a policy), the table of
variants in :mod:`.variants`, one variant's measurement in :mod:`.measure` and the
Markdown table in :mod:`.table`. ``docs/studies/fuzzy_design.py`` is the command line.
"""
