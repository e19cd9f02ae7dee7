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
propagation
    Batched RK4, adaptive DOP853 truth propagation, the closed-form axisymmetric motion.
jacobians
    Analytic Jacobians of the dynamics for EKFs and the discrete transition matrix.
arrays
    ``as_arrays`` (one array kind, numpy or torch, for all arguments), ``matvec``, ``cross``:
    the helpers every kernel above is written with, public for kernels outside the core.
"""

from filters.attitude.inertia import (
    InertiaError,
    inertia_from_normalized,
    inertia_from_tanh,
    inertia_ratios,
    normalized_from_inertia,
    principal_axes,
    ratios_from_tanh,
    tanh_from_inertia,
    validate_inertia,
)
from filters.attitude.jacobians import (
    error_state_matrix,
    euler_rate_jacobian,
    euler_rate_jacobian_normalized,
    euler_rate_jacobian_tanh,
    state_jacobian,
    transition_matrix,
)
from filters.attitude.kinematics import (
    cross_matrix,
    euler_rate,
    euler_rate_principal,
    omega_matrix,
    quaternion_rate,
    state_derivative,
    xi_matrix,
)
from filters.attitude.propagation import (
    PrincipalInertia,
    axisymmetric_solution,
    propagate,
    propagate_rk4,
    propagate_torque_free,
    rk4,
    rk4_step,
    torque_free_derivative,
    torque_free_trajectory,
)
from filters.attitude.quaternion import (
    attitude_angle,
    attitude_matrix,
    axis_angle_to_quaternion,
    euler321_to_quaternion,
    grp_to_quaternion,
    mrp_to_quaternion,
    quaternion_canonical,
    quaternion_conjugate,
    quaternion_from_matrix,
    quaternion_inverse,
    quaternion_mean,
    quaternion_multiply,
    quaternion_normalize,
    quaternion_to_euler321,
    quaternion_to_grp,
    quaternion_to_mrp,
    quaternion_to_rotation_vector,
    random_quaternion,
    rotate,
    rotation_vector_to_quaternion,
)

__all__ = [
    "InertiaError",
    "PrincipalInertia",
    "attitude_angle",
    "attitude_matrix",
    "axis_angle_to_quaternion",
    "axisymmetric_solution",
    "cross_matrix",
    "error_state_matrix",
    "euler321_to_quaternion",
    "euler_rate",
    "euler_rate_jacobian",
    "euler_rate_jacobian_normalized",
    "euler_rate_jacobian_tanh",
    "euler_rate_principal",
    "grp_to_quaternion",
    "inertia_from_normalized",
    "inertia_from_tanh",
    "inertia_ratios",
    "mrp_to_quaternion",
    "normalized_from_inertia",
    "omega_matrix",
    "principal_axes",
    "propagate",
    "propagate_rk4",
    "propagate_torque_free",
    "quaternion_canonical",
    "quaternion_conjugate",
    "quaternion_from_matrix",
    "quaternion_inverse",
    "quaternion_mean",
    "quaternion_multiply",
    "quaternion_normalize",
    "quaternion_rate",
    "quaternion_to_euler321",
    "quaternion_to_grp",
    "quaternion_to_mrp",
    "quaternion_to_rotation_vector",
    "random_quaternion",
    "ratios_from_tanh",
    "rk4",
    "rk4_step",
    "rotate",
    "rotation_vector_to_quaternion",
    "state_derivative",
    "state_jacobian",
    "tanh_from_inertia",
    "torque_free_derivative",
    "torque_free_trajectory",
    "transition_matrix",
    "validate_inertia",
    "xi_matrix",
]
