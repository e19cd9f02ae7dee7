"""`lightcurve plot`: states.png compares the estimates with the truth modulo the shape's
rotational symmetry group, as the summary's errors are taken.

An estimate at a symmetric twin of the truth (``s_g ⊗ q``, ``R_g ω``: it renders the same
light curve for all time) must plot as a near-zero attitude and rate error; a shape without
symmetry keeps the plain error. The tests check the plotted data (:func:`state_errors`),
not pixels.
"""

from __future__ import annotations

from functools import cache
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from filters.attitude import (
    attitude_matrix,
    axis_angle_to_quaternion,
    quaternion_multiply,
    rotation_vector_to_quaternion,
    torque_free_trajectory,
)
from filters.symmetry import SymmetryGroup
from lightcurve.inversion import shape_symmetry
from lightcurve.plots import InversionFolder, state_errors, state_figure
from shapes import get_library

N = 120
TIMES = np.arange(N) * 5.0


@cache
def group(name: str) -> SymmetryGroup:
    return shape_symmetry(get_library().load(name))


def truth(name: str) -> np.ndarray:
    """A torque-free truth (q, ω) of the named shape, tumbling at a few deg/s."""
    q0 = np.array([0.2, -0.4, 0.1, 0.9]) / np.linalg.norm([0.2, -0.4, 0.1, 0.9])
    omega0 = np.radians([1.5, -2.0, 3.0])
    q, omega = torque_free_trajectory(q0, omega0, TIMES, get_library().load(name).inertia)
    return np.concatenate([q, omega], axis=1)


def small_errors(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Attitude (rad, rotation vectors) and rate (rad/s) errors of a good estimate."""
    rng = np.random.default_rng(seed)
    return rng.normal(0, np.radians(0.5), (N, 3)), rng.normal(0, np.radians(0.01), (N, 3))


def twin_estimate(state: np.ndarray, rotations: np.ndarray, dtheta, domega):
    """``(δq ⊗ s ⊗ q, R ω + δω)`` with ``A(s) = R`` per epoch."""
    from filters.attitude import quaternion_from_matrix

    s = quaternion_from_matrix(rotations)
    q = quaternion_multiply(
        rotation_vector_to_quaternion(dtheta), quaternion_multiply(s, state[:, :4])
    )
    omega = np.einsum("nij,nj->ni", rotations, state[:, 4:]) + domega
    return q, omega


SIGMA_ATT_DEG = np.tile([1.0, 2.0, 3.0], (N, 1))
SIGMA_RATE = np.tile(np.radians([0.01, 0.02, 0.03]), (N, 1))


def errors(q, omega, state, shape_group):
    return state_errors(q, omega, SIGMA_ATT_DEG, SIGMA_RATE, state, shape_group)


def test_the_symmetric_twin_of_a_box_folds_to_the_truth():
    box = group("box")
    assert box.order == 4 and box.axis is None
    state = truth("box")
    dtheta, domega = small_errors()
    # One twin for the first half, another for the second: a multiple-hypothesis filter may
    # pass from one equivalent basin to another; the element is chosen per epoch.
    elements = np.where(np.arange(N) < N // 2, 1, 3)
    q, omega = twin_estimate(state, box.rotations[elements], dtheta, domega)

    plain = errors(q, omega, state, None)
    assert not plain.folded
    assert np.all(np.linalg.norm(plain.attitude_deg, axis=1) > 170)
    assert np.max(np.abs(plain.rate_deg_s)) > 1.0

    folded = errors(q, omega, state, box)
    assert folded.folded
    norm = np.linalg.norm(folded.attitude_deg, axis=1)
    assert np.max(norm) < 3.0
    np.testing.assert_allclose(norm, np.degrees(box.attitude_error(q, state[:, :4])), atol=1e-9)
    # the rate errors are those of the equivalent state: the added δω mapped back
    np.testing.assert_allclose(
        folded.rate_deg_s,
        np.degrees(np.einsum("nji,nj->ni", box.rotations[elements], domega)),
        atol=1e-9,
    )
    assert np.max(np.abs(folded.rate_deg_s)) < 0.05
    # inverse of the twin's element (the 180° turns are their own inverses)
    np.testing.assert_allclose(folded.rotations, box.rotations[elements], atol=1e-9)
    # 180° turns about body axes leave the per-axis 1σ as it is
    np.testing.assert_allclose(folded.sigma_attitude_deg, SIGMA_ATT_DEG)
    np.testing.assert_allclose(folded.sigma_rate_deg_s, np.degrees(SIGMA_RATE))


def test_a_quarter_turn_of_a_cube_permutes_the_bands():
    cube = group("cube")
    assert cube.order == 24
    angles = np.arccos(np.clip((np.trace(cube.rotations, axis1=1, axis2=2) - 1) / 2, -1, 1))
    quarter = cube.rotations[int(np.flatnonzero(np.isclose(angles, np.pi / 2))[0])]
    state = truth("cube")
    dtheta, domega = small_errors(1)
    rotations = np.broadcast_to(quarter.T, (N, 3, 3))  # the estimate sits at R⁻¹ of the truth
    q, omega = twin_estimate(state, rotations, dtheta, domega)
    folded = errors(q, omega, state, cube)
    assert np.max(np.linalg.norm(folded.attitude_deg, axis=1)) < 3.0
    assert np.max(np.abs(folded.rate_deg_s)) < 0.05
    np.testing.assert_allclose(folded.rotations, np.broadcast_to(quarter, (N, 3, 3)), atol=1e-9)
    # σ of R x for diagonal P: the quarter turn swaps two axes' bands
    np.testing.assert_allclose(
        folded.sigma_attitude_deg, SIGMA_ATT_DEG @ np.abs(quarter).T, atol=1e-9
    )
    assert not np.allclose(folded.sigma_attitude_deg, SIGMA_ATT_DEG)


def test_a_cylinder_folds_the_rotation_about_its_axis():
    cylinder = group("cylinder")
    assert cylinder.axis is not None
    state = truth("cylinder")
    dtheta, domega = small_errors(2)
    # any turn about the axis (not only the discrete elements) and a flip of the axis
    turn = np.linspace(0.3, 2.9, N)
    about_axis = attitude_matrix(axis_angle_to_quaternion(cylinder.axis, turn))
    flips = [r for r in cylinder.rotations if np.isclose(cylinder.axis @ r @ cylinder.axis, -1.0)]
    rotations = about_axis @ (flips[0] if flips else np.eye(3))
    q, omega = twin_estimate(state, rotations, dtheta, domega)
    folded = errors(q, omega, state, cylinder)
    norm = np.linalg.norm(folded.attitude_deg, axis=1)
    assert np.max(norm) < 3.0
    np.testing.assert_allclose(
        norm, np.degrees(cylinder.attitude_error(q, state[:, :4])), atol=1e-6
    )
    # the rotation about the axis is not counted: no error component along it
    np.testing.assert_allclose(folded.attitude_deg @ cylinder.axis, 0.0, atol=1e-9)
    # the turn that absorbs the 0.5° noise about the axis turns the ~4°/s rates with it
    assert np.max(np.abs(folded.rate_deg_s)) < 0.1
    assert np.max(np.linalg.norm(errors(q, omega, state, None).rate_deg_s, axis=1)) > 1.0


@pytest.mark.parametrize("name", ["itokawa", None])
def test_a_shape_without_symmetry_is_left_unfolded(name):
    shape_group = None if name is None else group(name)
    if shape_group is not None:
        assert shape_group.is_trivial
    state = truth("box")
    dtheta, domega = small_errors(3)
    flip = np.broadcast_to(np.diag([1.0, -1.0, -1.0]), (N, 3, 3))
    q, omega = twin_estimate(state, flip, dtheta, domega)
    folded = errors(q, omega, state, shape_group)
    plain = state_errors(q, omega, SIGMA_ATT_DEG, SIGMA_RATE, state)
    assert not folded.folded
    np.testing.assert_allclose(folded.attitude_deg, plain.attitude_deg)
    np.testing.assert_allclose(folded.rate_deg_s, plain.rate_deg_s)
    np.testing.assert_allclose(folded.rotations, np.broadcast_to(np.eye(3), (N, 3, 3)))
    assert np.all(np.linalg.norm(folded.attitude_deg, axis=1) > 170)


class _Observations(SimpleNamespace):
    def __len__(self) -> int:
        return len(self.truth)


def _folder(shape: str, shape_group: SymmetryGroup | None) -> InversionFolder:
    state = truth("box")
    dtheta, domega = small_errors(4)
    q, omega = twin_estimate(
        state, np.broadcast_to(group("box").rotations[2], (N, 3, 3)), dtheta, domega
    )
    estimates = pd.DataFrame(
        {
            "mjd": 60379.2 + TIMES / 86400.0,
            **{f"q{i + 1}": q[:, i] for i in range(4)},
            **{f"w{a}": omega[:, i] for i, a in enumerate("xyz")},
            **{f"sigma_att_{a}": SIGMA_ATT_DEG[:, i] for i, a in enumerate("xyz")},
            **{f"sigma_w{a}": SIGMA_RATE[:, i] for i, a in enumerate("xyz")},
        }
    )
    observations = _Observations(has_truth=True, truth=state)
    return InversionFolder(
        path=None,
        summary={"shape": shape},
        estimates=estimates,
        observations=observations,
        symmetry=shape_group,
    )


def _texts(fig) -> str:
    texts = [fig._suptitle.get_text() if fig._suptitle else ""]
    for ax in fig.axes:
        texts.append(ax.get_title())
        legend = ax.get_legend()
        if legend is not None:
            texts += [t.get_text() for t in legend.get_texts()]
    return " | ".join(texts)


def _largest_attitude_error(fig) -> float:
    """Largest |δθ_k| drawn in the left column (attitude errors)."""
    left = fig.axes[0::2]
    return max(float(np.max(np.abs(ax.get_lines()[0].get_ydata()))) for ax in left)


def test_the_figure_says_the_errors_are_modulo_the_group():
    import matplotlib.pyplot as plt

    fig = state_figure(_folder("box", group("box")))
    try:
        text = _texts(fig)
        assert "modulo the symmetry group of box (4 rotations)" in text
        assert "mod G" in text
        # the plotted lines are the folded error
        assert _largest_attitude_error(fig) < 3.0
    finally:
        plt.close(fig)
    fig = state_figure(_folder("itokawa", group("itokawa")))
    try:
        assert "modulo" not in _texts(fig) and "mod G" not in _texts(fig)
        assert _largest_attitude_error(fig) > 170
    finally:
        plt.close(fig)
