"""Stereo relative-navigation scenario files (Feng et al.).

A TOML file becomes a :class:`lightcurve.studies.stereo.StereoScenario`.

The ``lightcurve stereo`` command is a thin layer over this module.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from filters.attitude import euler321_to_quaternion
from filters.navigation.camera import PinholeCamera
from filters.navigation.hill import EARTH_MU, EARTH_RADIUS, mean_motion
from filters.navigation.stereo import StereoCamera
from lightcurve.scenarios import ScenarioError, load_toml
from lightcurve.studies.stereo import StereoScenario


def load_stereo_scenario(path: str | Path) -> StereoScenario:
    """Read a stereo scenario TOML file (format in ``docs/stereo.md``).

    Parameters
    ----------
    path : str or pathlib.Path

    Returns
    -------
    StereoScenario
        In SI units (degrees and kilometres converted here).

    Raises
    ------
    ScenarioError
        Naming the file, table and field of the first problem.
    """
    root = load_toml(path)
    orbit, cam, target, noise, sim, filt = root.tables(
        "orbit", "camera", "target", "noise", "simulation", "filter"
    )

    n = mean_motion(EARTH_RADIUS + 1e3 * orbit.number("altitude_km", positive=True), EARTH_MU)
    width = cam.integer("image_width_px", minimum=1)
    height = cam.integer("image_height_px", minimum=1)
    fov = cam.number("field_of_view_deg", positive=True)
    if fov >= 180:
        raise cam.error("field_of_view_deg", f"must be below 180, got {fov}")
    stereo = StereoCamera(
        PinholeCamera.from_fov(fov, width, height), cam.number("baseline_m", positive=True)
    )
    axes = cam.array("axes_in_hill", (3, 3))

    coords = target.array("feature_coordinates", (None, 3))
    sigma = {
        "attitude": math.radians(filt.number("sigma_attitude_deg", positive=True)),
        "omega": math.radians(filt.number("sigma_rate_deg_s", positive=True)),
        "k": filt.number("sigma_k", positive=True),
        "position": filt.number("sigma_position_m", positive=True),
        "velocity": filt.number("sigma_velocity_m_s", positive=True),
    }
    fields: dict[str, Any] = {
        "mean_motion": n,
        "camera_from_hill": axes,
        "stereo": stereo,
        "feature_coordinates": coords,
        "feature_count": target.integer("feature_count", minimum=3),
        "target_size": target.number("size_m", positive=True),
        "inertia": target.array("principal_inertia_kg_m2", (3,)),
        "attitude": euler321_to_quaternion(
            np.radians(target.array("initial_attitude_321_deg", (3,)))
        ),
        "omega": np.radians(target.array("initial_rate_deg_s", (3,))),
        "position": target.array("initial_position_m", (3,)),
        "velocity": target.array("initial_velocity_m_s", (3,)),
        "angle_noise": noise.number("angle_rad", positive=True),
        "angular_acceleration_psd": noise.number("angular_acceleration_rad_s2_rthz", minimum=0)
        ** 2,
        "acceleration_psd": noise.number("acceleration_m_s2_rthz", minimum=0) ** 2,
        "duration": sim.number("duration_s", positive=True),
        "step": sim.number("step_s", positive=True),
        "window": sim.number("window_s", positive=True),
        "truth_substeps": sim.integer("truth_substeps", 2, minimum=1),
        "initial_attitude_error": np.radians(filt.array("initial_attitude_error_deg", (3,))),
        "initial_k": filt.array("initial_k", (2,)),
        "sigma": sigma,
    }
    for table in (root, orbit, cam, target, noise, sim, filt):
        table.check_unknown()
    try:
        return StereoScenario(**fields)
    except ValueError as exc:  # cross-field checks (window vs duration, inertia, ...)
        raise ScenarioError(f"{root.path}: {exc}") from None
