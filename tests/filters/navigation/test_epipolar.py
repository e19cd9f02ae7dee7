"""Essential-matrix pipeline: exact recovery, RANSAC, refinement, attitude chains from pixels."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from torch.func import jacfwd

import shapes
from filters.attitude import (
    attitude_angle,
    attitude_matrix,
    propagate,
    quaternion_from_matrix,
    rotation_vector_to_quaternion,
)
from filters.navigation.camera import PinholeCamera
from filters.navigation.epipolar import (
    EpipolarError,
    RelativePose,
    _pose_jacobian,
    _pose_residuals,
    _tangent_basis,
    attitude_sequence,
    decompose_essential,
    eight_point,
    pose_from_essential,
    ransac_essential,
    refine_poses,
    sampson_error,
)
from filters.navigation.features import FeatureTracks, camera_points, simulate_tracks
from shapes.visibility.raycast import Occluder

J_A = np.array([[0.85, 0.13, 0.17], [0.13, 1.37, -0.11], [0.17, -0.11, 1.0]])
CAMERA = PinholeCamera.from_fov(60.0, 1024)


def _angle_deg(r1: np.ndarray, r2: np.ndarray) -> float:
    q = quaternion_from_matrix(np.stack([r1, r2]))
    return float(np.degrees(attitude_angle(q[0], q[1])))


def _rotating_pair(rotvec, rng, n=60, noise=0.0):
    """Points of a body rotating about its centre 3 m in front of the camera."""
    p_b = rng.normal(size=(n, 3)) * 0.5
    centre = np.array([0.0, 0.0, 3.0])
    r = np.asarray(attitude_matrix(rotation_vector_to_quaternion(np.asarray(rotvec))))
    p1, p2 = p_b + centre, p_b @ r.T + centre
    x1, x2 = p1[:, :2] / p1[:, 2:], p2[:, :2] / p2[:, 2:]
    t = centre - r @ centre
    return x1 + noise * rng.normal(size=x1.shape), x2 + noise * rng.normal(size=x2.shape), r, t


@settings(max_examples=20, deadline=None)
@given(rotvec=st.lists(st.floats(-0.3, 0.3), min_size=3, max_size=3), seed=st.integers(0, 999))
def test_eight_point_and_cheirality_recover_the_exact_pose(rotvec, seed):
    if np.linalg.norm(np.cross(rotvec, [0, 0, 1])) < 0.02:
        return  # rotation about the line of sight: no translation, E is undefined
    x1, x2, r, t = _rotating_pair(rotvec, np.random.default_rng(seed))
    e = eight_point(x1, x2)
    assert np.max(np.abs(sampson_error(e, x1, x2))) < 1e-9
    assert np.allclose(np.linalg.svd(e)[1], [1, 1, 0], atol=1e-9)
    r_hat, t_hat, in_front = pose_from_essential(e, x1, x2)
    assert in_front == x1.shape[0]
    assert _angle_deg(r_hat, r) < 1e-6
    assert np.allclose(t_hat, t / np.linalg.norm(t), atol=1e-6)
    # Exactly one of the four decompositions puts the points in front of both cameras.
    assert len(decompose_essential(e)) == 4


def test_ransac_rejects_mismatches():
    rng = np.random.default_rng(4)
    x1, x2, r, _ = _rotating_pair([0.05, -0.08, 0.03], rng, n=120, noise=1e-4)
    bad = rng.random(120) < 0.3
    x2 = x2.copy()
    x2[bad] = rng.uniform(-0.4, 0.4, size=(bad.sum(), 2))
    e, inliers = ransac_essential(x1, x2, threshold=5e-4, rng=rng)
    assert np.all(~inliers[bad]) and inliers[~bad].mean() > 0.95
    r_hat, _, _ = pose_from_essential(e, x1[inliers], x2[inliers])
    assert _angle_deg(r_hat, r) < 0.1
    with pytest.raises(EpipolarError, match="at least 8"):
        ransac_essential(x1[:7], x2[:7], threshold=5e-4, rng=rng)


def test_pose_jacobian_matches_autograd():
    rng = np.random.default_rng(0)
    rot = np.asarray(attitude_matrix(rotation_vector_to_quaternion(0.1 * rng.normal(size=(3, 3)))))
    trans = rng.normal(size=(3, 3))
    trans /= np.linalg.norm(trans, axis=-1, keepdims=True)
    basis = _tangent_basis(trans)
    x1 = 0.2 * rng.normal(size=(3, 25, 2))
    x2 = x1 + 0.01 * rng.normal(size=(3, 25, 2))
    analytic = _pose_jacobian(rot, trans, basis, x1, x2)
    for p in range(3):
        args = [torch.as_tensor(a[p : p + 1]) for a in (rot, trans, basis, x1, x2)]
        auto = jacfwd(lambda v, a=args: _pose_residuals(v[None], *a)[0])(
            torch.zeros(5, dtype=torch.float64)
        )
        assert np.max(np.abs(auto.numpy() - analytic[p])) < 1e-12


def test_refinement_improves_noisy_poses_and_its_covariance_is_calibrated():
    rng = np.random.default_rng(8)
    poses, pairs, truths = [], [], []
    for i in range(40):
        x1, x2, r, _ = _rotating_pair(rng.normal(size=3) * 0.08, rng, n=80, noise=3e-4)
        e, inl = ransac_essential(x1, x2, threshold=2e-3, rng=rng)
        r0, t0, _ = pose_from_essential(e, x1[inl], x2[inl])
        poses.append(RelativePose(i, i + 1, r0, t0, 80, int(inl.sum())))
        pairs.append((x1[inl], x2[inl]))
        truths.append(r)
    linear = np.array([_angle_deg(p.rotation, r) for p, r in zip(poses, truths, strict=True)])
    refine_poses(poses, pairs, focal=1000.0, iterations=10)
    refined = np.array([_angle_deg(p.rotation, r) for p, r in zip(poses, truths, strict=True)])
    assert np.sqrt(np.mean(refined**2)) < 0.8 * np.sqrt(np.mean(linear**2))
    # Normalised squared rotation errors average ~3 (χ² with 3 dof) when the covariance is right.
    nees = []
    for p, r in zip(poses, truths, strict=True):
        dq = quaternion_from_matrix((p.rotation @ r.T)[None])[0]
        theta = 2 * dq[:3]
        nees.append(theta @ np.linalg.solve(p.rotation_covariance, theta))
    assert 1.5 < np.mean(nees) < 6.0
    assert np.median([p.residual_rms_px for p in poses]) == pytest.approx(0.3, rel=0.3)


@pytest.fixture(scope="module")
def bennu_tracks():
    """60 s of scenario A seen from 2.5 radii with the library's Bennu vertices as features."""
    model = shapes.get_library().load("bennu")
    v = np.asarray(model.vertices) - np.asarray(model.center_of_mass)
    v /= np.max(np.linalg.norm(v, axis=1))
    t = np.arange(0.0, 61.0, 1.0)
    states = propagate(np.r_[0, 0, 0, 1.0, np.radians([5.0, 2.3, 3.5])], t, J_A)
    tracks = simulate_tracks(
        v,
        np.asarray(model.mesh.vertex_normals),
        states[:, :4],
        t,
        CAMERA,
        position=[0.0, 0.0, 2.5],
        pixel_sigma=0.1,
        rng=np.random.default_rng(2),
        occluded=Occluder(v, model.faces),
    )
    return tracks, states


def test_tracks_cull_back_faces_and_occluded_points(bennu_tracks):
    tracks, states = bennu_tracks
    n_points = tracks.visible.shape[1]
    assert 0.2 * n_points < tracks.visible.sum(axis=1).min() < 0.6 * n_points
    assert np.all(np.isnan(tracks.pixels[~tracks.visible]))
    assert not tracks.outlier.any()
    # Tracked pixels sit within a few sigma of the noiseless projection.
    model = shapes.get_library().load("bennu")
    v = np.asarray(model.vertices) - np.asarray(model.center_of_mass)
    v /= np.max(np.linalg.norm(v, axis=1))
    clean = np.asarray(CAMERA.project(camera_points(v, states[:, :4], [0, 0, 2.5])))
    dev = (tracks.pixels - clean)[tracks.visible]
    assert np.std(dev) == pytest.approx(0.1, rel=0.1)


def test_pixels_give_relative_attitudes_within_0p2_deg(bennu_tracks):
    """Relative attitudes from pixels (per frame pair): 1024² camera, 0.1 px, hundreds of
    library-shape points."""
    tracks, states = bennu_tracks
    seq = attitude_sequence(tracks, CAMERA, rng=np.random.default_rng(0))
    assert not seq.failures
    a = np.asarray(attitude_matrix(states[:, :4]))
    pair_err = [_angle_deg(p.rotation, a[p.second].T @ a[p.first]) for p in seq.poses]
    assert min(p.inliers for p in seq.poses) >= 20
    assert max(pair_err) < 0.2
    att_err = np.degrees(np.asarray(attitude_angle(seq.quaternions, states[:, :4])))
    assert np.max(att_err) < 0.2
    # The estimated accumulated sigma is the right order of magnitude.
    assert 0.2 < np.sqrt(np.mean(att_err**2)) / np.degrees(np.sqrt(np.mean(seq.sigma**2))) < 5


def test_linking_shortens_the_chain_of_the_consecutive_product(bennu_tracks):
    """Eq. 9 over consecutive frames has one link per frame; "best" keeps paths short."""
    tracks, states = bennu_tracks
    depth, err = {}, {}
    for linking in ("previous", "best"):
        seq = attitude_sequence(tracks, CAMERA, rng=np.random.default_rng(0), linking=linking)
        depth[linking] = seq.depth
        err[linking] = np.degrees(np.asarray(attitude_angle(seq.quaternions, states[:, :4])))
    assert np.array_equal(depth["previous"], np.arange(61))
    assert depth["best"].max() <= 15
    assert np.max(err["previous"]) < 0.5 and np.max(err["best"]) < 0.2


def test_a_frame_without_enough_points_is_skipped_and_recorded(bennu_tracks):
    tracks, states = bennu_tracks
    visible = tracks.visible.copy()
    visible[5, 7:] = False  # frame 5 keeps only 7 points
    cut = FeatureTracks(tracks.times, tracks.pixels, visible, tracks.outlier)
    seq = attitude_sequence(cut, CAMERA, rng=np.random.default_rng(0), linking="previous")
    assert list(seq.failures) == [5] and "8" in seq.failures[5]
    assert np.all(np.isnan(seq.quaternions[5]))
    # The chain continues from frame 4 to frame 6.
    assert any(p.first == 4 and p.second == 6 for p in seq.poses)
    assert np.degrees(attitude_angle(seq.quaternions[-1], states[-1, :4])) < 1.0
