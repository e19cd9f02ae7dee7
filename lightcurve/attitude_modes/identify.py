"""Identify the attitude mode of a light curve: every hypothesis fitted per candidate shape,
weighed by its evidence (:mod:`lightcurve.attitude_modes`)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from filters.attitude import attitude_angle
from filters.global_search import BatchProblem
from lightcurve.attitude_modes.evidence import mode_probabilities
from lightcurve.attitude_modes.hypotheses import MODE_HYPOTHESES, stabilised, tumbling
from lightcurve.attitude_modes.results import ModeIdentification
from lightcurve.photometry.measurement import PhotometricModel
from lightcurve.photometry.profiles import offset_quaternion


def identify_attitude_mode(
    model: PhotometricModel,
    problem: BatchProblem,
    tumbling_starts: dict[int, list[tuple[np.ndarray, np.ndarray, float]]],
    symmetry_orders: Sequence[int],
    *,
    omega_max: float = math.radians(5.0),
    offset_sigma_deg: float = 10.0,
    weak_sigma_deg: float = 1.0,
    consistency_level: float = 0.999,
    search_candidates: int = 4096,
    min_epochs: int = 90,
    max_rotation: float = math.radians(20.0),
    position: np.ndarray | None = None,
    velocity: np.ndarray | None = None,
    seed: int = 0,
) -> ModeIdentification:
    """Weigh stabilised attitude profiles against tumbling (see the package doc).

    Parameters
    ----------
    model : PhotometricModel
        Measurements and candidate shapes.
    problem : BatchProblem
        The torque-free batch problem of the same measurements (the inversion's).
    tumbling_starts : dict
        Shape index → list of ``(q, ω, t)`` states of the tumbling inversion (attitude,
        rad/s, at time ``t`` s on the problem's axis) to grow the whole-arc fit from.
    symmetry_orders : sequence of int
        Order of each shape's rotational symmetry group.
    omega_max : float
        Radius of the tumbling rate prior (rad/s).
    offset_sigma_deg : float
        1σ per axis of the profile offsets' prior (deg).
    weak_sigma_deg : float
        Offset directions whose Laplace 1σ exceeds this (deg) are reported as weak axes
        with a profile-likelihood interval (:class:`WeakAxis`).
    consistency_level : float
        Quantile of the consistency test.
    search_candidates : int
        Uniform attitudes screened for the inertial hypothesis (a quarter as many offsets
        for the other profiles).
    min_epochs : int
        Measurements per window of the tumbling fit's growing windows, at least (as the
        global search's ``min_epochs``).
    max_rotation : float
        Longest rotation (rad) between the measurements of such a window (as the global
        search's).
    position, velocity : (n, 3) arrays, optional
        Geocentric object position and velocity (any consistent units): without them the
        nadir hypotheses are left out (noted).
    seed : int
        Seeds the inertial and offset scans and, on a stream of its own, the sampler of the
        winning offset's posterior.

    Returns
    -------
    ModeIdentification
    """
    seeds = np.random.SeedSequence(seed)
    rng = np.random.default_rng(seeds)
    sigma = math.radians(offset_sigma_deg)
    notes = []
    labels = list(MODE_HYPOTHESES)
    if position is None or velocity is None:
        labels = [lab for lab in labels if MODE_HYPOTHESES[lab][0] != "nadir"]
        notes.append("no object position/velocity columns: nadir hypotheses left out")
    hypotheses = []
    for s in range(model.n_shapes):
        starts = tumbling_starts.get(s, [])
        shared = {"symmetry_order": symmetry_orders[s], "consistency_level": consistency_level}
        tumbler = (
            tumbling(
                model,
                problem,
                s,
                starts=starts,
                omega_max=omega_max,
                min_epochs=min_epochs,
                max_rotation=max_rotation,
                **shared,
            )
            if starts
            else None
        )
        extra = [q for q, _, t in starts if t == 0.0]
        hypotheses.extend(
            stabilised(
                model,
                s,
                label,
                position=position,
                velocity=velocity,
                offset_sigma=sigma,
                search_candidates=search_candidates,
                rng=rng,
                extra_starts=extra,
                weak_sigma=math.radians(weak_sigma_deg),
                **shared,
            )
            for label in labels
        )
        if tumbler is not None:
            hypotheses.append(tumbler)
    probabilities = mode_probabilities(hypotheses, labels, model.n_shapes)
    mode = max(probabilities, key=probabilities.get)
    best = max((h for h in hypotheses if h.mode == mode), key=lambda h: h.probability)
    if best.posterior_sampler is not None:
        # The sampled offset posterior of the winning profile and shape (its own stream).
        best.posterior = best.posterior_sampler(seed=seeds.spawn(1)[0])
    return ModeIdentification(
        mode=mode,
        probability=probabilities[mode],
        probabilities=probabilities,
        best=best,
        hypotheses=hypotheses,
        none_fits=not any(h.consistent for h in hypotheses),
        notes=notes,
    )


def offset_error_deg(estimated_deg: Sequence[float], true_deg: Sequence[float]) -> float:
    """Angle (deg) between two offsets given as ``[roll, pitch, yaw]`` (deg)."""
    return math.degrees(
        float(attitude_angle(offset_quaternion(estimated_deg), offset_quaternion(true_deg)))
    )
