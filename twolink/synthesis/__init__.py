"""The makers of fuzzy policies: fuzzy Q-iteration (Alg. 1) on the two-link arm's
problems (:mod:`twolink.synthesis.problems`) and on N-link arms
(:mod:`twolink.synthesis.links_centralized`, :mod:`twolink.synthesis.links_decentralized`),
:func:`twolink.synthesis.synthesize.synthesize` over both, and online fuzzy Q-learning on
the arm itself (:mod:`twolink.synthesis.learning`). What acts (controllers, baselines,
loaders of learned agents) is :mod:`twolink.control`; the time-optimal limit is
:mod:`twolink.limits`."""
