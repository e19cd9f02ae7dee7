"""Models and estimators of close-range and relative navigation.

Modules
-------
camera
    Pinhole camera: projection, back-projection, field of view.
features
    Feature tracks of a tumbling target seen by a fixed camera.
essential
    Two-view geometry: the essential matrix of a frame pair and the relative pose in it.
epipolar
    Relative rotations from matched pixel tracks (eight-point, LO-RANSAC, refinement;
    Deng et al. 2024).
monocular
    Monocular attitude, rate and inertia EKF of a tumbling target (Deng et al. 2024).
stereo
    Stereo relative-state and inertia EKF of a tumbling target (Feng et al.).
hill
    Clohessy–Wiltshire (Hill) relative dynamics about a circular orbit.
relnav
    Relative-navigation Kalman filter with IMU input and robust fixes (Shi et al.).
gravity
    Small-body gravity: point mass plus normalised spherical harmonics.
lander
    Landing navigation near a rotating small body: dynamics, landmarks, iterated EKF
    (Li et al. 2024).

The Monte Carlo studies that run these estimators on the papers' scenarios are in
:mod:`lightcurve.studies`.
"""
