"""The attitude core shared by every estimator and by the light-curve simulator.

Quaternions are scalar-last and passive: ``v_B = A(q) v_I`` (see ``docs/conventions.md``).
Every function accepts numpy arrays or torch tensors with leading batch dimensions and
returns the same kind.

Submodules
----------
quaternion
    Algebra, attitude matrix, rotation vector / GRP / MRP / 3-2-1 Euler conversions,
    attitude error angle, uniform random attitudes, the weighted quaternion mean.
kinematics
    ``Ω(ω)``, ``q̇``, Euler's equations (full tensor, normalised ``L``, principal ratios).
inertia
    Validity checks, principal axes, the ``L = J/Jzz`` and tanh ``k`` parameterisations.
principal_rk4
    Compiled RK4 chains of torque-free motion in principal axes (numba).
propagation
    Batched RK4, adaptive DOP853 truth propagation, the closed-form axisymmetric motion.
torque_free_periods
    Rotation and mean precession periods of non-principal-axis rotation (closed form and
    integrated), the SAM/LAM mode.
torque_free_motion
    Closed-form torque-free attitude about the angular momentum (Jacobi elliptic functions),
    scale-free: a function of time in rotation periods.
jacobians
    Analytic Jacobians of the dynamics for EKFs and the discrete transition matrix.
arrays
    ``as_arrays`` (one array kind, numpy or torch, for all arguments), ``matvec``, ``cross``:
    the helpers every kernel above is written with, public for kernels outside the core.
"""

from filters.attitude import (
    inertia,
    jacobians,
    kinematics,
    propagation,
    quaternion,
    torque_free_motion,
    torque_free_periods,
)
from filters.attitude.inertia import *  # noqa: F403
from filters.attitude.jacobians import *  # noqa: F403
from filters.attitude.kinematics import *  # noqa: F403
from filters.attitude.propagation import *  # noqa: F403
from filters.attitude.quaternion import *  # noqa: F403
from filters.attitude.torque_free_motion import *  # noqa: F403
from filters.attitude.torque_free_periods import *  # noqa: F403

# The public names are those of the submodules (each lists its own in ``__all__``).
__all__ = sorted(
    [
        *inertia.__all__,
        *jacobians.__all__,
        *kinematics.__all__,
        *propagation.__all__,
        *quaternion.__all__,
        *torque_free_motion.__all__,
        *torque_free_periods.__all__,
    ]
)
