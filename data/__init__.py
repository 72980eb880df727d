"""Shipped data tables (installed as the package ``twolink._data``): ``limits.json``, the
time-optimal limits T*(x) of the evaluation states (``twolink limits``)."""
