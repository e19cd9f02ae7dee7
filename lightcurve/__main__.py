"""``python -m lightcurve``: the same command line as the ``lightcurve`` script."""

from lightcurve.cli import main

raise SystemExit(main())
