"""Small-body landing scenarios for observation planning (Li et al. 2024): the scenario file, the
Monte Carlo study of the three imaging strategies, and its summary.

The ``lightcurve plan`` command is a thin layer over this module.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from filters.navigation.camera import PinholeCamera
from filters.navigation.gravity import SphericalHarmonicGravity
from filters.navigation.lander import (
    DescentTrajectory,
    LanderDynamics,
    LanderModel,
    LandmarkMap,
    NadirPointing,
    SiteFrame,
    anchor_pixels,
)
from lightcurve.scenarios import TomlTable, load_toml
from lightcurve.studies.landing import LandingScenario


def _vector(table: TomlTable, field: str, size: int = 3) -> np.ndarray:
    return table.array(field, (size,))


def load_scenario(path: str | Path) -> LandingScenario:
    """Read a landing scenario TOML file (format in ``docs/planner.md``).

    Parameters
    ----------
    path : str or pathlib.Path

    Returns
    -------
    LandingScenario
        In SI units (degrees and hours converted here).

    Raises
    ------
    ScenarioError
        Naming the file, table and field of the first problem.
    """
    root = load_toml(path)
    body, site_t, traj, cam_t, marks, noise, filt, plan = root.tables(
        "body", "site", "trajectory", "camera", "landmarks", "noise", "filter", "planner"
    )

    body.string("name", "")
    degree = body.integer("gravity_degree", minimum=0)
    rows = body.array("gravity_coefficients", (None, 4), [])
    try:
        gravity = SphericalHarmonicGravity.from_coefficients(
            body.number("mu_m3_s2", positive=True),
            body.number("reference_radius_m", positive=True),
            rows.tolist(),
            degree,
        )
    except ValueError as exc:
        raise body.error("gravity_coefficients", str(exc)) from None
    spin = np.array(
        [0.0, 0.0, 2 * math.pi / (3600.0 * body.number("spin_period_h", positive=True))]
    )

    try:
        site = SiteFrame(_vector(site_t, "position_m"))
    except ValueError as exc:
        raise site_t.error("position_m", str(exc)) from None
    duration = traj.number("duration_s", positive=True)
    dt = traj.number("step_s", positive=True)
    steps = round(duration / dt)
    if not math.isclose(steps * dt, duration, rel_tol=1e-9) or steps < 2:
        raise traj.error("step_s", f"must divide duration_s={duration} into at least 2 steps")
    trajectory = DescentTrajectory(
        _vector(traj, "start_position_m"),
        _vector(traj, "start_velocity_m_s"),
        _vector(traj, "end_position_m"),
        _vector(traj, "end_velocity_m_s"),
        duration,
    )
    periods = _vector(traj, "wobble_period_s")
    if np.any(periods <= 0):
        raise traj.error("wobble_period_s", "periods must be positive")
    pointing = NadirPointing(site, np.radians(_vector(traj, "wobble_amplitude_deg")), periods)

    try:
        camera = PinholeCamera.from_fov(
            cam_t.number("fov_deg", positive=True), cam_t.integer("pixels", minimum=16)
        )
    except ValueError as exc:
        raise cam_t.error("fov_deg", str(exc)) from None
    per_image = cam_t.integer("landmarks_per_image", minimum=3)

    extent = marks.array("extent_m", (4,))
    spacing = marks.number("spacing_m", positive=True)
    cells = (extent[1] - extent[0]) * (extent[3] - extent[2]) / spacing**2
    if not 3 <= cells <= 5e6:
        raise marks.error("spacing_m", f"gives {cells:.3g} landmarks over extent_m (3 … 5e6)")
    try:
        landmarks = LandmarkMap.jittered_grid(
            site,
            tuple(extent),
            spacing,
            marks.number("relief_m", minimum=0.0),
            np.random.default_rng(marks.integer("seed", minimum=0)),
        )
    except ValueError as exc:
        raise marks.error("extent_m", str(exc)) from None

    model = LanderModel(
        dynamics=LanderDynamics(gravity, spin).feedforward(trajectory, site),
        pointing=pointing,
        landmarks=landmarks,
        camera=camera,
        pixel_sigma=cam_t.number("pixel_noise_px", positive=True),
        anchors=anchor_pixels(camera, per_image),
        dt=dt,
        acceleration_psd=noise.number("acceleration_m_s2_per_sqrt_hz", minimum=0.0) ** 2,
        attitude_psd=math.radians(noise.number("attitude_deg_per_sqrt_s", minimum=0.0)) ** 2,
        estimate_attitude=filt.boolean("estimate_attitude", True),
    )
    sigma = np.concatenate(
        [
            _vector(filt, "initial_position_error_m"),
            _vector(filt, "initial_velocity_error_m_s"),
            np.radians(_vector(filt, "initial_attitude_error_deg")),
        ]
    )
    if np.any(sigma[: model.dim] <= 0):
        raise filt.error("initial_position_error_m", "initial error sigmas must be positive")
    settle = plan.number("settle_time_s", minimum=0.0)
    settle_step = math.ceil(settle / dt - 1e-9)
    if settle_step >= steps:
        raise plan.error("settle_time_s", f"must be before the end of the descent ({duration} s)")
    scenario = LandingScenario(
        model=model,
        trajectory=trajectory,
        initial_sigma=sigma,
        steps=steps,
        settle_step=settle_step,
        s_max=plan.integer("s_max", minimum=1),
        iterations=filt.integer("iterations", 10, minimum=1),
    )
    for table in (root, body, site_t, traj, cam_t, marks, noise, filt, plan):
        table.check_unknown()
    return scenario
