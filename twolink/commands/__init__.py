"""Subcommands of the ``twolink`` command line, one module each."""
