"""Relative rotation of a non-cooperative target from matched pixel tracks (Deng et al. 2024).

Between two frames a body point moves as ``P₂ = R_Δ P₁ + t_Δ`` in the camera frame (eq. 3),
so matched normalised image points satisfy the epipolar constraint ``x₂ᵀ E x₁ = 0`` with the
essential matrix ``E = [t_Δ×] R_Δ``. Scale is not needed for the rotation. The pipeline:

1. Hartley-normalised eight-point estimate of ``E`` (Hartley 1997), batched over RANSAC
   hypotheses; inliers by the Sampson distance with an adaptive number of samples (MSAC
   scoring);
2. decomposition ``E = U diag(1, 1, 0) Vᵀ`` into four ``(R, t)`` candidates and the
   cheirality check (triangulated points in front of both cameras; Hartley & Zisserman
   2004, sec. 9.6);
3. optional Levenberg–Marquardt refinement of ``(R, t)`` on the Sampson errors of all
   inliers, batched over every frame pair with analytic Jacobians (checked against torch
   autograd in the tests); the same Jacobian gives the rotation covariance ``σ̂² (JᵀJ)⁻¹``;
4. the attitude relative to the first frame as the product of relative rotations,
   ``R_t = R_Δt ⋯ R_Δ2 R_Δ1`` (eq. 9), converted to the filter's quaternion
   (``A(q_t) = R_tᵀ``, since ``P_C = A(q)ᵀ p + T``), with an accumulated noise level.

A frame pair that cannot be solved (too few matches, no consensus) is recorded with its
reason; the chain then continues from the last good frame to the next one.

Steps 1 and 2 are :mod:`filters.navigation.essential` (its names are importable from here).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from filters.attitude import (
    attitude_angle,
    attitude_matrix,
    quaternion_canonical,
    quaternion_conjugate,
    quaternion_from_matrix,
    quaternion_multiply,
    rotation_vector_to_quaternion,
)
from filters.attitude.arrays import as_arrays
from filters.attitude.kinematics import cross_matrix
from filters.navigation.camera import PinholeCamera
from filters.navigation.essential import (
    EpipolarError,
    decompose_essential,
    eight_point,
    homogeneous,
    pose_from_essential,
    ransac_essential,
    sampson_error,
)
from filters.navigation.features import FeatureTracks

__all__ = [
    "AttitudeSequence",
    "EpipolarError",
    "RelativePose",
    "attitude_sequence",
    "decompose_essential",
    "eight_point",
    "pose_from_essential",
    "ransac_essential",
    "refine_poses",
    "sampson_error",
]

_MAX_TRIES = 3  # reference frames tried per new frame


def _pose_residuals(
    params: Any, rotation: Any, translation: Any, basis: Any, x1: Any, x2: Any
) -> Any:
    """Sampson errors ``(P, M)`` of the local poses ``(exp(θ) R, normalise(t + B β))``.

    ``params = [θ (3), β (2)]``; ``exp(θ)`` is the passive rotation
    ``A(rotation_vector_to_quaternion(θ)) ≈ I − [θ×]``. numpy or torch.
    """
    xp, (params, rotation, translation, basis) = as_arrays(params, rotation, translation, basis)
    r = attitude_matrix(rotation_vector_to_quaternion(params[..., :3])) @ rotation
    t = translation + (basis @ params[..., 3:, None])[..., 0]
    t = t / xp.linalg.vector_norm(t, axis=-1, keepdims=True)
    return sampson_error(cross_matrix(t) @ r, x1, x2)


def _pose_jacobian(
    rotation: np.ndarray, translation: np.ndarray, basis: np.ndarray, x1: np.ndarray, x2: np.ndarray
) -> np.ndarray:
    """Analytic ``∂r/∂[θ, β]`` of :func:`_pose_residuals` at zero, shape ``(P, M, 5)``.

    With ``r = n/d``, ``n = y₂ᵀEy₁``, ``a = Ey₁``, ``b = Eᵀy₂``, ``d² = a₁² + a₂² + b₁² + b₂²``:
    ``∂r/∂E = y₂y₁ᵀ/d − n/d³ (P (a y₁ᵀ) + (y₂ bᵀ) P)`` with ``P = diag(1, 1, 0)``, and
    ``∂E/∂θ_k = −[t×][e_k×]R``, ``∂E/∂β_m = [B_m×]R`` (``E = [t×]R``).
    """
    e = np.asarray(cross_matrix(translation)) @ rotation
    y1 = homogeneous(x1)
    y2 = homogeneous(x2)
    a = y1 @ np.swapaxes(e, -1, -2)
    b = y2 @ e
    n = np.sum(y2 * a, axis=-1)
    d = np.sqrt(a[..., 0] ** 2 + a[..., 1] ** 2 + b[..., 0] ** 2 + b[..., 1] ** 2)
    a[..., 2] = 0.0
    b[..., 2] = 0.0
    grad = (y2[..., :, None] * y1[..., None, :]) / d[..., None, None] - (n / d**3)[
        ..., None, None
    ] * (a[..., :, None] * y1[..., None, :] + y2[..., :, None] * b[..., None, :])
    eye = np.eye(3)
    t_cross = np.asarray(cross_matrix(translation))
    d_theta = -t_cross[:, None] @ np.asarray(cross_matrix(eye))[None] @ rotation[:, None]
    d_beta = np.asarray(cross_matrix(np.swapaxes(basis, -1, -2))) @ rotation[:, None]
    d_e = np.concatenate([d_theta, d_beta], axis=1)  # (P, 5, 3, 3)
    return np.einsum("pmij,pkij->pmk", grad, d_e)


@dataclass
class RelativePose:
    """Relative pose of one frame pair.

    Attributes
    ----------
    first, second : int
        Frame indices.
    rotation : (3, 3) numpy.ndarray
        ``R_Δ`` (camera frame, ``P₂ = R_Δ P₁ + t``).
    translation : (3,) numpy.ndarray
        Unit translation direction.
    matches, inliers : int
        Matched points and RANSAC inliers.
    rotation_covariance : (3, 3) numpy.ndarray
        Covariance of the small rotation ``δθ`` of ``R_Δ`` (rad²).
    residual_rms_px : float
        RMS Sampson error of the inliers (pixels).
    """

    first: int
    second: int
    rotation: np.ndarray
    translation: np.ndarray
    matches: int
    inliers: int
    rotation_covariance: np.ndarray = field(default_factory=lambda: np.full((3, 3), np.nan))
    residual_rms_px: float = float("nan")


def _tangent_basis(t: np.ndarray) -> np.ndarray:
    """(P, 3, 2) orthonormal bases of the planes orthogonal to unit vectors ``t``."""
    _, _, vt = np.linalg.svd(t[:, None, :])
    return np.swapaxes(vt[:, 1:], -1, -2)


def _apply_step(
    params: np.ndarray, rot: np.ndarray, trans: np.ndarray, basis: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Fold local parameters into the reference poses (``exp(θ) R``, ``normalise(t + B β)``)."""
    rot = np.asarray(attitude_matrix(rotation_vector_to_quaternion(params[:, :3]))) @ rot
    t = trans + (basis @ params[:, 3:, None])[..., 0]
    return rot, t / np.linalg.norm(t, axis=-1, keepdims=True)


def refine_poses(
    poses: list[RelativePose],
    pairs: list[tuple[np.ndarray, np.ndarray]],
    focal: float,
    iterations: int = 10,
) -> None:
    """Levenberg–Marquardt refinement and covariance of many relative poses at once.

    Minimises the Sampson errors of each pair's inliers over ``(R, t)`` (5 parameters:
    a small rotation and two tangent directions of the unit translation), all pairs in one
    batch with per-pair damping; analytic Jacobians. The rotation covariance is
    ``σ̂² (JᵀJ)⁻¹`` restricted to the rotation, ``σ̂²`` the residual variance. Poses are
    updated in place.

    Parameters
    ----------
    poses : list of RelativePose
        Initial poses (from :func:`pose_from_essential`).
    pairs : list of (x1 (M_i, 2), x2 (M_i, 2))
        Their inlier matches (normalised coordinates).
    focal : float
        Focal length in pixels (to report residuals in pixels).
    iterations : int
        LM iterations; 0 keeps the linear estimate and only computes the covariance.
    """
    if not poses:
        return
    width = max(x1.shape[0] for x1, _ in pairs)
    count = len(poses)
    x1 = np.zeros((count, width, 2))
    x2 = np.zeros((count, width, 2))
    mask = np.zeros((count, width))
    for i, (a, b) in enumerate(pairs):
        x1[i, : a.shape[0]], x2[i, : a.shape[0]], mask[i, : a.shape[0]] = a, b, 1.0
    # Pad with copies of the first match (masked out) so every residual stays finite.
    pad = mask == 0
    x1[pad] = np.repeat(x1[:, :1], width, axis=1)[pad]
    x2[pad] = np.repeat(x2[:, :1], width, axis=1)[pad]
    rot = np.stack([p.rotation for p in poses])
    trans = np.stack([p.translation for p in poses])
    zero = np.zeros((count, 5))
    lam = np.full(count, 1e-3)
    for iteration in range(iterations + 1):
        basis = _tangent_basis(trans)
        r = _pose_residuals(zero, rot, trans, basis, x1, x2) * mask
        j = _pose_jacobian(rot, trans, basis, x1, x2) * mask[..., None]
        jtj = np.swapaxes(j, -1, -2) @ j
        if iteration == iterations:
            break
        diag = np.einsum("pii->pi", jtj)
        damped = jtj + lam[:, None, None] * (diag[:, :, None] * np.eye(5))
        step = -np.linalg.solve(damped, (np.swapaxes(j, -1, -2) @ r[..., None]))[..., 0]
        trial = _pose_residuals(step, rot, trans, basis, x1, x2) * mask
        better = np.sum(trial**2, -1) < np.sum(r**2, -1)
        new_rot, new_trans = _apply_step(step, rot, trans, basis)
        rot = np.where(better[:, None, None], new_rot, rot)
        trans = np.where(better[:, None], new_trans, trans)
        lam = np.where(better, lam * 0.3, lam * 10.0)
    dof = np.maximum(mask.sum(-1) - 5, 1.0)
    sigma2 = np.sum(r**2, -1) / dof
    cov = np.linalg.pinv(jtj)[:, :3, :3] * sigma2[:, None, None]
    for i, pose in enumerate(poses):
        pose.rotation = rot[i]
        pose.translation = trans[i]
        pose.rotation_covariance = cov[i]
        pose.residual_rms_px = float(focal * math.sqrt(float(sigma2[i])))


@dataclass
class AttitudeSequence:
    """Attitude measurements relative to the first frame, from pixel tracks.

    Attributes
    ----------
    times : (K,) numpy.ndarray
        Frame times (s).
    quaternions : (K, 4) numpy.ndarray
        ``q_t`` with ``A(q_t) = R_tᵀ`` (identity at the first frame); NaN rows for frames
        that could not be linked.
    sigma : (K,) numpy.ndarray
        Estimated one-sigma error per axis of each attitude (rad): the per-pair covariances
        summed along its chain of links back to the first frame.
    poses : list of RelativePose
        The solved frame pairs, one per linked frame (``pose.second``).
    failures : dict of int to str
        Frames that could not be linked, with the reason.
    """

    times: np.ndarray
    quaternions: np.ndarray
    sigma: np.ndarray
    poses: list[RelativePose]
    failures: dict[int, str]

    @property
    def pair_sigma(self) -> np.ndarray:
        """One-sigma per-axis rotation error of each solved pair (rad)."""
        return np.array([math.sqrt(np.trace(p.rotation_covariance) / 3) for p in self.poses])

    @property
    def depth(self) -> np.ndarray:
        """Number of links between each frame and the first one (``-1`` if unlinked)."""
        depth = np.full(self.times.size, -1)
        depth[0] = 0
        for pose in self.poses:
            depth[pose.second] = depth[pose.first] + 1
        return depth


def _reference_candidates(
    k: int,
    visible: np.ndarray,
    q: np.ndarray,
    links: np.ndarray,
    *,
    linking: str,
    min_matches: int,
    baseline: tuple[float, float],
) -> list[int]:
    """Earlier frames to link frame ``k`` to, best first."""
    solved = np.flatnonzero(np.isfinite(q[:k, 0]))
    if linking == "previous":
        return [int(solved[-1])]
    common = visible[solved].astype(np.int64) @ visible[k].astype(np.int64)
    ok = common >= min_matches
    if solved.size >= 2:
        # Predict q_k by repeating the last step; a reference must be rotated away from it,
        # or the translation (I − R_Δ)T vanishes and the essential matrix degenerates.
        a, b = q[solved[-1]], q[solved[-2]]
        step = quaternion_multiply(quaternion_conjugate(b), a)
        predicted = quaternion_multiply(a, step)
        angle = np.asarray(attitude_angle(q[solved], predicted))
        ok &= (angle >= baseline[0]) & (angle <= baseline[1])
    if not np.any(ok):
        return [int(solved[-1])]
    # Accumulated variance in units of one link with `min_matches` points: the path to the
    # reference plus the new link, whose variance falls like 1/matches.
    score = links[solved] + min_matches / np.maximum(common, 1)
    # Stable: equal scores (same link count and matches) keep frame order on every CPU.
    order = np.argsort(np.where(ok, score, np.inf), kind="stable")[:_MAX_TRIES]
    return [int(solved[i]) for i in order if ok[i]]


def attitude_sequence(
    tracks: FeatureTracks,
    camera: PinholeCamera,
    *,
    rng: np.random.Generator,
    threshold_px: float = 1.0,
    refine_iterations: int = 10,
    linking: str = "best",
    min_matches: int = 30,
    baseline_deg: tuple[float, float] = (3.0, 45.0),
) -> AttitudeSequence:
    """Attitudes of every frame relative to the first by chaining relative rotations (eq. 9).

    ``linking="previous"`` is the paper's chain ``R_t = R_Δt ⋯ R_Δ1`` over consecutive
    frames; its error is a random walk that grows with the number of frames. ``"best"``
    links each frame to the earlier frame that shares at least ``min_matches`` points, is
    rotated by an angle inside ``baseline_deg`` from it (too little rotation degenerates the
    essential matrix, too much foreshortens the shared view), and minimises the accumulated
    variance of the path back to the first frame (a tumbling body shows the same faces again,
    so paths stay short and the drift stays bounded). Both are products of relative
    rotations.

    Parameters
    ----------
    tracks : FeatureTracks
    camera : PinholeCamera
    rng : numpy.random.Generator
        For RANSAC sampling.
    threshold_px : float
        RANSAC inlier threshold (pixels).
    refine_iterations : int
        Levenberg–Marquardt iterations of the pose refinement (0 = linear estimate only).
    linking : {"best", "previous"}
    min_matches : int
        Matches a reference frame must share with the new frame (``"best"`` only).
    baseline_deg : (float, float)
        Allowed rotation between reference and new frame, degrees (``"best"`` only; the
        rotation is predicted from the last two linked frames).

    Returns
    -------
    AttitudeSequence
    """
    if linking not in ("best", "previous"):
        raise ValueError(f"linking must be 'best' or 'previous', got {linking!r}")
    focal = math.sqrt(camera.fx * camera.fy)
    size = len(tracks)
    q = np.full((size, 4), np.nan)
    q[0] = [0.0, 0.0, 0.0, 1.0]
    links = np.full(size, np.inf)
    links[0] = 0.0
    poses: list[RelativePose] = []
    pairs: list[tuple[np.ndarray, np.ndarray]] = []
    failures: dict[int, str] = {}
    for k in range(1, size):
        reasons = []
        for j in _reference_candidates(
            k,
            tracks.visible,
            q,
            links,
            linking=linking,
            min_matches=min_matches,
            baseline=tuple(np.radians(baseline_deg)),
        ):
            _, uv1, uv2 = tracks.matches(j, k)
            x1, x2 = np.asarray(camera.normalized(uv1)), np.asarray(camera.normalized(uv2))
            try:
                e, inl = ransac_essential(x1, x2, threshold=threshold_px / focal, rng=rng)
                r, t, _ = pose_from_essential(e, x1[inl], x2[inl])
            except EpipolarError as exc:
                reasons.append(f"frames {j}->{k}: {exc}")
                continue
            poses.append(RelativePose(j, k, r, t, x1.shape[0], int(inl.sum())))
            pairs.append((x1[inl], x2[inl]))
            q[k] = _compose(q[j], r)
            links[k] = links[j] + min_matches / max(int(inl.sum()), 1)
            break
        else:
            failures[k] = "; ".join(reasons) or "no earlier frame shares enough points"
    refine_poses(poses, pairs, focal, refine_iterations)
    sigma = np.full(size, np.nan)
    sigma[0] = 0.0
    for pose in poses:  # in frame order, so every reference is final before it is used
        q[pose.second] = _compose(q[pose.first], pose.rotation)
        sigma[pose.second] = math.sqrt(
            sigma[pose.first] ** 2 + float(np.trace(pose.rotation_covariance)) / 3
        )
    return AttitudeSequence(tracks.times, quaternion_canonical(q), sigma, poses, failures)


def _compose(q_reference: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """``q_k`` with ``A(q_k) = A(q_j) R_Δᵀ`` (``R_k = R_Δ R_j`` and ``A(q) = Rᵀ``)."""
    r = quaternion_from_matrix(rotation.T)
    return np.asarray(quaternion_multiply(q_reference, r))
