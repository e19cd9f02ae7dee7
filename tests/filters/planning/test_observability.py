"""Observability: Lie-derivative rank test and Fisher information against closed forms."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from filters.attitude import normalized_from_inertia, propagate
from filters.navigation.monocular import FORMS, observability_at, trajectory_information
from filters.planning.observability import (
    Chart,
    canonical_basis,
    fisher_information,
    information_sigmas,
    lie_derivatives,
    observability_gramian,
    observability_matrix,
    rank_test,
)

J_A = np.array([[0.85, 0.13, 0.17], [0.13, 1.37, -0.11], [0.17, -0.11, 1.0]])
J_B = np.diag([0.85, 1.37, 1.0])

# A linear system with a known unobservable direction: x3 never reaches the output.
A = torch.tensor([[0.0, 1.0, 0.0], [-2.0, -0.3, 0.0], [0.0, 0.0, 0.5]], dtype=torch.float64)
C = torch.tensor([[1.0, 0.0, 0.0]], dtype=torch.float64)


def test_lie_derivatives_of_a_linear_system_are_c_a_powers():
    x = torch.tensor([0.3, -1.2, 2.0], dtype=torch.float64)
    f, h = (lambda s: A @ s), (lambda s: C @ s)
    values = lie_derivatives(f, h, x, 3)
    q = observability_matrix(f, h, x, 3)
    powers = [torch.linalg.matrix_power(A, k) for k in range(4)]
    assert torch.allclose(values[:, 0], torch.stack([(C @ p @ x)[0] for p in powers]))
    assert torch.allclose(q, torch.cat([C @ p for p in powers]))
    test = rank_test(q)
    assert test.rank == 2
    assert np.allclose(np.abs(test.null_space[:, 0]), [0, 0, 1])
    (direction,) = test.unobservable_directions(["x1", "x2", "x3"])
    assert list(direction) == ["x3"] and direction["x3"] == pytest.approx(1.0, abs=1e-12)


def test_canonical_basis_does_not_depend_on_the_basis_it_is_given():
    """Any basis of one subspace (as different BLAS kernels return) gives one canonical form."""
    rng = np.random.default_rng(7)
    axes = np.eye(6)[:, [4, 1, 3]]  # coordinate axes, out of order
    general = np.linalg.qr(rng.normal(size=(6, 3)))[0]
    for subspace in (axes, general):
        reference = canonical_basis(subspace)
        for _ in range(20):
            mixing = np.linalg.qr(rng.normal(size=(3, 3)))[0]  # rotation or reflection
            assert np.allclose(canonical_basis(subspace @ mixing), reference, atol=1e-12)
        # same span, unit columns, leading (pivot) components positive and in state order
        assert np.linalg.matrix_rank(np.hstack([subspace, reference]), tol=1e-9) == 3
        assert np.allclose(np.linalg.norm(reference, axis=0), 1.0)
        leading = [int(np.flatnonzero(np.abs(c) > 1e-12)[0]) for c in reference.T]
        assert leading == sorted(leading) and all(
            reference[i, j] > 0 for j, i in enumerate(leading)
        )
    assert np.allclose(canonical_basis(axes), np.eye(6)[:, [1, 3, 4]])


def test_a_chart_counts_the_rank_in_local_coordinates():
    """Embedding a 2-D state in 3-D (x3 = 0 fixed by the chart) drops the null direction."""
    x = torch.tensor([0.3, -1.2, 0.0], dtype=torch.float64)
    chart = Chart(2, lambda d: torch.cat([x[:2] + d, torch.zeros(1, dtype=d.dtype)]))
    q = observability_matrix(lambda s: A @ s, lambda s: C @ s, x, 2, chart)
    assert q.shape == (3, 2)
    assert rank_test(q).rank == 2


def test_scenario_a_is_fully_observable_at_the_true_state():
    """Nutating body: rank 11 (Deng et al. 2024, eq. 21) with a clear singular-value gap."""
    x = np.r_[0, 0, 0, 1.0, np.radians([5.0, 2.3, 3.5]), normalized_from_inertia(J_A)]
    test = observability_at(x, "L", max_order=4)
    assert test.rank == 11 and test.full
    assert test.order <= 4
    sv = test.singular_values
    assert sv[-1] / sv[0] > 1e-4 > test.tolerance / sv[0]


def test_scenario_b_loses_exactly_three_inertia_directions():
    """Pure spin: rank 8 < 11 (eq. 23); unobservable Lxx, Lyy, Lxz."""
    x = np.r_[0, 0, 0, 1.0, np.radians([0.0, 2.3, 0.0]), normalized_from_inertia(J_B)]
    test = observability_at(x, "L", max_order=5)
    assert test.rank == 8
    assert test.singular_values[8] < 1e-14 * test.singular_values[0]
    directions = test.unobservable_directions(FORMS["L"].state_names)
    assert [list(d) for d in directions] == [["Lxx"], ["Lyy"], ["Lxz"]]
    assert all(d[name] == pytest.approx(1.0, abs=1e-9) for d in directions for name in d)


def test_unobservable_directions_are_exact_output_invariances():
    """Independent check: moving along a null direction leaves the attitude history unchanged."""
    t = np.linspace(0, 300, 61)
    x0 = np.r_[0, 0, 0, 1.0, np.radians([0.0, 2.3, 0.0])]
    base = propagate(x0, t, J_B)
    for delta in ([0.2, 0, 0, 0, 0], [0, 0.3, 0, 0, 0], [0, 0, 0, 0.1, 0]):
        l = normalized_from_inertia(J_B) + np.array(delta)
        j = np.array([[l[0], l[2], l[3]], [l[2], l[1], l[4]], [l[3], l[4], 1.0]])
        assert np.max(np.abs(propagate(x0, t, j)[:, :4] - base[:, :4])) < 1e-9
    # ... whereas an observable one (Lxy) changes it.
    l = normalized_from_inertia(J_B) + np.array([0, 0, 0.05, 0, 0])
    j = np.array([[l[0], l[2], l[3]], [l[2], l[1], l[4]], [l[3], l[4], 1.0]])
    assert np.max(np.abs(propagate(x0, t, j)[:, :4] - base[:, :4])) > 1e-3


def test_fisher_information_of_a_linear_system_is_the_discrete_gramian():
    a = np.array([[1.0, 0.1, 0.0], [-0.2, 0.97, 0.0], [0.0, 0.0, 1.05]])
    c = np.array([[1.0, 0.0, 0.0]])
    r = np.array([[0.04]])
    k = 20
    w = fisher_information(np.repeat(a[None], k, 0), np.repeat(c[None], k + 1, 0), r)
    ref = sum(
        np.linalg.matrix_power(a, i).T @ c.T @ np.linalg.inv(r) @ c @ np.linalg.matrix_power(a, i)
        for i in range(k + 1)
    )
    assert np.allclose(w, ref, rtol=1e-12)
    sig = information_sigmas(w)
    assert np.isinf(sig[2]) and np.all(np.isfinite(sig[:2]))


def test_autograd_gramian_matches_the_linear_one():
    dt = 0.1
    a_d = torch.linalg.matrix_exp(A * dt)
    states = torch.stack(
        [torch.linalg.matrix_power(a_d, k) @ torch.ones(3, dtype=torch.float64) for k in range(11)]
    )
    w = observability_gramian(
        lambda x, h: torch.linalg.matrix_exp(A * h) @ x,
        lambda x: C @ x,
        states,
        torch.arange(11, dtype=torch.float64) * dt,
        np.eye(1),
    )
    ref = fisher_information(
        np.repeat(a_d.numpy()[None], 10, 0), np.repeat(C.numpy()[None], 11, 0), np.eye(1)
    )
    assert np.allclose(w, ref, atol=1e-12)


def test_monocular_information_separates_scenarios_a_and_b():
    """Continuous measure: finite Cramér–Rao bounds for A, infinite for B's null directions."""
    t = np.arange(0.0, 301.0, 2.0)
    out = {}
    for name, j, w in (("A", J_A, [5.0, 2.3, 3.5]), ("B", J_B, [0.0, 2.3, 0.0])):
        states = propagate(np.r_[0, 0, 0, 1.0, np.radians(w)], t, j)
        x = np.concatenate([states, np.tile(normalized_from_inertia(j), (t.size, 1))], 1)
        out[name] = information_sigmas(trajectory_information(x, t, 0.01, "L"))
    assert np.all(np.isfinite(out["A"])) and np.all(out["A"][6:] < 0.05)
    assert np.isinf(out["B"][[6, 7, 9]]).all()
    assert np.isfinite(out["B"][[8, 10]]).all()


def test_rank_test_rejects_bad_scales():
    with pytest.raises(ValueError, match="positive"):
        rank_test(np.eye(2), scales=[1.0, 0.0])
