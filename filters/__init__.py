"""Estimation: the attitude core and the filters built on it.

``filters.attitude`` owns all quaternion algebra, kinematics, torque-free dynamics, inertia
parameterisations and propagation; every estimator in this package uses it and none
re-implements it. Estimators take their dynamics and measurement models as callables, so this
package depends on no other project package.
"""
