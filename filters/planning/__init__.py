"""Observation planning and observability analysis.

Modules
-------
information
    The planning-model protocol, Fisher information and covariance forecasts (Li et al. 2024).
sequential
    After each update, when to observe next: Fisher-trace and posterior-rollout criteria.
schedule
    Offline observation sets for the final covariance (greedy with exchanges, RTS reductions).
keyframes
    Keyframes of a recorded frame sequence for the monocular EKF.
observability
    Nonlinear observability: Lie-derivative rank test, Fisher information and Gramian along
    a trajectory.
"""
