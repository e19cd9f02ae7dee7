"""Estimation: the attitude core and the filters built on it.

``filters.attitude`` owns all quaternion algebra, kinematics, torque-free dynamics, inertia
parameterisations and propagation; every estimator in this package uses it and none
re-implements it. Estimators take their dynamics and measurement models as callables, so this
package depends on no other project package.

Modules
-------
- :mod:`~filters.consistency` — Filter consistency over a sliding window of normalised
  innovations squared.
- :mod:`~filters.gaussian` — Gaussian estimation algebra shared by the EKFs and UKFs of this
  package.
- :mod:`~filters.linalg` — Batched square roots of covariance matrices that survive degenerate
  input (torch).
- :mod:`~filters.mmae` — Multiple-model adaptive estimation: a bank of attitude UKFs, one per
  candidate model.
- :mod:`~filters.particle` — Particle filter for attitude, rates, optional inertia and a
  discrete shape index.
- :mod:`~filters.particle_modes` — Modes of a weighted particle cloud over ``(q, ω[, k][,
  shape])``.
- :mod:`~filters.resampling` — Systematic resampling of weighted particles (Kitagawa 1996,
  "Monte Carlo filter and smoother for non-Gaussian nonlinear state space models"), optionally
  within consecutive blocks (the components of a mixture, Vermaak, Doucet & Pérez 2003).
- :mod:`~filters.robust` — Huber M-estimation for Kalman measurement updates (the "robust
  M-estimation" of the multimodal relative navigation of Shi, Zhang, Li, Lang & Zheng).
- :mod:`~filters.roughening` — Roughening of a resampled particle cloud: per-cluster Gaussian
  kernels on SO(3) × ℝⁿ.
- :mod:`~filters.symmetry` — Rotational symmetry of a facet model and attitude errors modulo
  that symmetry.
- :mod:`~filters.ukf` — Attitude unscented Kalman filter: USQUE with generalized Rodrigues
  parameters.
- :mod:`~filters.ukf_models` — The models an attitude UKF propagates with: torque-free dynamics
  and process noise.
- :mod:`~filters.attitude` — The attitude core shared by every estimator and by the light-curve
  simulator (package).
- :mod:`~filters.global_search` — Global initialisation of attitude, rates (and shape) from a
  light curve (package).
- :mod:`~filters.gnss` — Relative GNSS for cooperative targets: almanac constellation, simulated
  receivers, double differences, LAMBDA integer ambiguities, and the relative positioning solver
  (package).
- :mod:`~filters.navigation` — Models and estimators of close-range and relative navigation
  (package).
- :mod:`~filters.planning` — Observation planning and observability analysis (package).
"""
