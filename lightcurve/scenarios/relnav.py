"""Relative-navigation approach scenario files (seed 003).

A TOML file becomes a :class:`filters.relnav.ApproachScenario`.

The ``lightcurve relnav`` command is a thin layer over this module.
"""

from __future__ import annotations

from pathlib import Path

from filters.hill import EARTH_MU, EARTH_RADIUS, mean_motion
from filters.relnav import ApproachScenario, PositionSensor
from lightcurve.scenarios import ScenarioError, load_toml

_AXES = ("x", "y", "z", "vx", "vy", "vz")


def load_relnav_scenario(path: str | Path) -> tuple[ApproachScenario, int]:
    """Read a relative-navigation scenario TOML file (format in ``docs/relnav.md``).

    Parameters
    ----------
    path : str or pathlib.Path

    Returns
    -------
    scenario : ApproachScenario
    seed : int
        The file's default random seed.

    Raises
    ------
    ScenarioError
        Naming the file, table and field of the first problem.
    """
    root = load_toml(path)
    orbit, traj = root.table("orbit"), root.table("trajectory")
    control, imu, sensors_table = root.table("control"), root.table("imu"), root.table("sensors")
    modes_table, filt, evaluation = (
        root.table("modes"),
        root.table("filter"),
        root.table("evaluation"),
    )

    sensors = {}
    for name in sensors_table.data:
        table = sensors_table.table(name)
        sensors[name] = PositionSensor(
            name,
            table.number("sigma_m", positive=True),
            table.number("period_s", positive=True),
            table.boolean("optical", False),
        )
        table.check_unknown()
    modes = {}
    for name, value in modes_table.data.items():
        if not (isinstance(value, list) and all(isinstance(v, str) for v in value) and value):
            raise modes_table.error(name, "must be a non-empty list of sensor names")
        unknown = [v for v in value if v not in sensors]
        if unknown:
            raise modes_table.error(name, f"unknown sensor {unknown[0]!r} (not in [sensors])")
        modes[name] = tuple(value)
    mode = root.string("mode", choices=modes)

    altitude = orbit.number("altitude_km", positive=True)
    fields = {
        "mean_motion": mean_motion(EARTH_RADIUS + 1e3 * altitude, EARTH_MU),
        "start": traj.array("start_position_m", (3,)),
        "hold": traj.array("hold_position_m", (3,)),
        "approach_duration": traj.number("approach_duration_s", positive=True),
        "duration": traj.number("duration_s", positive=True),
        "imu_period": control.number("period_s", positive=True),
        "control_frequency": control.number("natural_frequency_rad_s", positive=True),
        "control_damping": control.number("damping", positive=True),
        "thrust_noise": control.number("thrust_noise_m_s2", minimum=0.0),
        "accelerometer_noise": imu.number("accelerometer_noise_m_s2", positive=True),
        "sensors": sensors,
        "modes": modes,
        "mode": mode,
        "initial_sigma_position": filt.number("initial_sigma_position_m", positive=True),
        "initial_sigma_velocity": filt.number("initial_sigma_velocity_m_s", positive=True),
        "huber_threshold": filt.number("huber_threshold", positive=True),
        "settle": evaluation.number("settle_s", minimum=0.0),
    }
    seed = evaluation.integer("seed", 0, minimum=0)
    for table in (root, orbit, traj, control, imu, filt, evaluation):
        table.check_unknown()
    try:
        return ApproachScenario(**fields), seed
    except ValueError as exc:
        raise ScenarioError(f"{root.path}: {exc}") from None
