"""Guided learning at six links: demonstrations from the reach study's solver, cloned into
a residual agent's policy, then fine-tuned by PPO (``docs/studies/links_guided.py``)."""
