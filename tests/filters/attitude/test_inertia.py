"""Inertia parameterisations and validity checks (Deng et al. 2024; Feng et al.)."""

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from filters.attitude import (
    InertiaError,
    euler_rate,
    euler_rate_principal,
    inertia_from_normalized,
    inertia_from_tanh,
    inertia_ratios,
    moment_ratios,
    normalized_from_inertia,
    principal_axes,
    ratios_from_tanh,
    tanh_from_inertia,
    validate_inertia,
)

J_NUTATION = np.array([[0.85, 0.13, 0.17], [0.13, 1.37, -0.11], [0.17, -0.11, 1.0]])


def test_normalized_round_trip():
    l = normalized_from_inertia(J_NUTATION * 7.0)
    np.testing.assert_allclose(l, [0.85, 1.37, 0.13, 0.17, -0.11], atol=1e-15)
    np.testing.assert_allclose(inertia_from_normalized(l), J_NUTATION, atol=1e-15)


@settings(max_examples=300, deadline=None)
@given(st.floats(-8, 8), st.floats(-8, 8))
def test_every_k_is_physical_and_round_trips(k1, k2):
    k = np.array([k1, k2])
    j = inertia_from_tanh(k)
    validate_inertia(j)
    p = inertia_ratios(j)
    assert abs(p[0] + p[1] + p[2] + p[0] * p[1] * p[2]) < 1e-12
    np.testing.assert_allclose(p, ratios_from_tanh(k), atol=1e-9)
    if max(abs(k1), abs(k2)) < 6:
        # atanh amplifies a ratio's rounding error by d(atanh r)/dr = cosh²(k) near r = ±1.
        tolerance = 1e-10 * np.cosh(k) ** 2
        assert np.all(np.abs(tanh_from_inertia(j) - k) <= tolerance)


def test_j_to_k_to_j_up_to_scale():
    j = np.diag([3.0, 4.0, 5.0])
    back = inertia_from_tanh(tanh_from_inertia(j))
    np.testing.assert_allclose(back / back[2, 2], j / j[2, 2], atol=1e-14)


def test_ratio_identity_for_physical_bodies():
    rng = np.random.default_rng(20)
    moments = rng.uniform(1, 2, (1000, 3))
    ok = (moments.sum(1) - 2 * moments.max(1)) > 0
    p = inertia_ratios(moments[ok])
    np.testing.assert_allclose(p[:, 0] + p[:, 1] + p[:, 2] + np.prod(p, axis=1), 0, atol=1e-14)
    assert np.all(np.abs(p) < 1)


def test_moment_ratios_read_a_stack_of_three_bodies_as_three_bodies():
    """A ``(3, 3)`` array of moments is three bodies for :func:`moment_ratios`, while
    :func:`inertia_ratios` reads it as one diagonal tensor."""
    moments = np.array([[260.4, 208.3, 135.4], [1.0, 1.0, 1.0], [0.83, 3.33, 4.17]])
    each = np.stack([inertia_ratios(m) for m in moments])
    np.testing.assert_allclose(moment_ratios(moments), each, atol=1e-15)
    np.testing.assert_allclose(inertia_ratios(np.diag(moments[0])), each[0], atol=1e-15)


def test_principal_dynamics_equal_full_tensor():
    rng = np.random.default_rng(21)
    j = np.diag([2.0, 3.0, 4.0])
    w = rng.normal(size=(10, 3))
    np.testing.assert_allclose(
        euler_rate_principal(w, inertia_ratios(j)), euler_rate(w, j), atol=1e-14
    )


def test_principal_axes_diagonalise():
    moments, axes = principal_axes(J_NUTATION)
    np.testing.assert_allclose(axes.T @ J_NUTATION @ axes, np.diag(moments), atol=1e-14)
    assert np.linalg.det(axes) == pytest.approx(1.0)


@pytest.mark.parametrize(
    ("tensor", "message"),
    [
        (np.diag([1.0, 1.0, 3.0]), r"triangle inequality J1 \+ J2 >= J3"),
        (np.diag([1.0, -1.0, 1.0]), "not positive definite"),
        (np.array([[1.0, 0.2, 0], [0.0, 1, 0], [0, 0, 1]]), "not symmetric"),
        (np.diag([1.0, np.nan, 1.0]), "non-finite"),
        (np.ones((2, 2)), "shape"),
    ],
)
def test_unphysical_inertia_is_rejected_with_reason(tensor, message):
    with pytest.raises(InertiaError, match=message):
        validate_inertia(tensor)


def test_thin_plate_is_physical_but_has_no_tanh_form():
    plate = np.diag([1.0, 2.0, 3.0])
    validate_inertia(plate)
    with pytest.raises(InertiaError, match="strictly"):
        tanh_from_inertia(plate)
    with pytest.raises(InertiaError, match="principal-axis"):
        tanh_from_inertia(J_NUTATION)


def test_the_nearest_tanh_form_of_a_plate_keeps_its_third_ratio():
    """With a margin, a flat body (J3 = J1 + J2) gets a tanh form whose ratios are the
    plate's to the margin, not a disc's (pz = 0); a body inside the triangle is unchanged."""
    for moments in ([1.0, 2.0, 3.0], [1.0, 4.0, 5.0], [1.0, 1.0, 2.0]):
        k = tanh_from_inertia(np.array(moments), margin=1e-6)
        np.testing.assert_allclose(
            ratios_from_tanh(k), inertia_ratios(np.array(moments)), atol=1e-5
        )
    body = np.array([1.0, 2.0, 2.5])
    np.testing.assert_array_equal(tanh_from_inertia(body, margin=1e-6), tanh_from_inertia(body))


def test_tanh_is_differentiable_in_torch():
    k = torch.tensor([0.3, -0.2], dtype=torch.float64, requires_grad=True)
    ratios_from_tanh(k).sum().backward()
    assert torch.all(torch.isfinite(k.grad))
    big = inertia_from_tanh(torch.tensor([400.0, -400.0], dtype=torch.float64))
    assert torch.all(torch.isfinite(big))
