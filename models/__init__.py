"""The committed MJCF model (installed as the package ``twolink._models``)."""
