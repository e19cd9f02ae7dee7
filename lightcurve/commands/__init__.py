"""Subcommands of the ``lightcurve`` CLI, one module each (see :mod:`lightcurve.cli`)."""
