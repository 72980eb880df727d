"""What acts on the arm: the controller protocol's resolver (:mod:`.controllers`) and
catalogue (:mod:`.catalogue`), the classical baselines (:mod:`.baselines`), the N-link
per-joint PD (:mod:`.links_pd`), the time-optimal MPC (:mod:`.mpc`) and the loaders of
learned agents (:mod:`.sb3_agent`, :mod:`.learned`). The makers of fuzzy policies are
:mod:`twolink.synthesis`; the time-optimal limit is :mod:`twolink.limits`.
"""
