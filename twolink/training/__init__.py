"""Deep RL on the arm, as a command (``twolink train``) and its API: :mod:`.config`
(:class:`~twolink.training.config.TrainConfig`, the algorithms, hyperparameters and the
environment's options), :mod:`.run` (:func:`~twolink.training.run.train`: training,
evaluation, the learning curve and the saved agent) and :mod:`.checkpoint` (checkpoints
that resume a run exactly, read without unpickling). Needs the rl extras
(Stable-Baselines3 and torch) at run time only.
"""
