"""The shipped policy files (installed as the package ``twolink._policies``)."""
