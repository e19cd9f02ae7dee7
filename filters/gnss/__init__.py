"""Relative GNSS for cooperative targets: almanac constellation, simulated receivers, double
differences, LAMBDA integer ambiguities, and the relative positioning solver.

Modules
-------
constellation
    YUMA almanac parsing; satellite positions, velocities and clocks (IS-GPS-200).
measurements
    Simulated L1 code and carrier phase of spacecraft receivers: clocks, ambiguities, cycle
    slips, multipath, elevation masks and Earth blockage.
differencing
    Common view, single and double differences and their correlated covariance.
lambda_
    LAMBDA decorrelation and integer search, ratio test, bootstrapped success rate.
smoothing
    Carrier-smoothed code (Hatch filter) of between-receiver single differences.
snapshot
    Single point positioning, double-difference geometry and one epoch's normal equations.
ambiguity
    Double-difference ambiguity normal equations accumulated over epochs, keyed by PRN.
relative
    Code (raw and carrier-smoothed), float and fixed double-difference relative positioning
    epoch by epoch, with cycle-slip detection and time-differenced carrier-phase velocity.
formation
    Seeded simulation of a two-spacecraft LEO formation and its scores.

All estimators take arrays (satellite states, measurements); files are read by the callers.
Frame: the week-start inertial frame of :mod:`filters.gnss.constellation`.
"""
