"""Monte Carlo studies that the command line offers to users, one module per study.

Each module holds the study's definition (the scenario dataclass the TOML reader of
:mod:`lightcurve.scenarios` fills), its Monte Carlo driver and its summary; the command of the
same name in :mod:`lightcurve.commands` is a thin layer over it. The estimators and models the
studies run live in :mod:`filters`; validation studies that no command exposes live in
``benchmarks/``.

Modules
-------
landing
    Observation planning for small-body landing (Li et al. 2024): ``lightcurve plan``.
monocular
    Attitude, rate and inertia of a tumbling target from images (Deng et al. 2024):
    ``lightcurve monocular``.
monocular_definition
    What a monocular study is (the scenario) and what one run of it produced.
monocular_summary
    The figures of a monocular study: errors, convergence, Monte Carlo table, plots.
relnav
    Multi-mode relative navigation of an approach (Shi et al.): ``lightcurve relnav``.
stereo
    Stereo relative-state and inertia estimation (Feng et al.): ``lightcurve stereo``.
"""
