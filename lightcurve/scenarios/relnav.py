"""Relative-navigation approach scenario files (Shi et al., multimodal relative navigation).

A TOML file becomes a :class:`lightcurve.studies.relnav.ApproachScenario`; sensor tables of
``kind = "rgnss"`` become :class:`lightcurve.studies.relnav.RgnssSensor` with their almanac
read from the file they name (relative to the scenario file).

The ``lightcurve relnav`` command is a thin layer over this module.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from filters.gnss.constellation import AlmanacError, parse_yuma
from filters.gnss.measurements import ReceiverModel
from filters.gnss.relative import RelativeGnssConfig
from filters.navigation.hill import EARTH_MU, EARTH_RADIUS, mean_motion
from lightcurve.scenarios import ScenarioError, TomlTable, load_toml
from lightcurve.studies.relnav import ApproachScenario, PositionSensor, RgnssSensor

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
    orbit, traj, control, imu, sensors_table, modes_table, filt, evaluation = root.tables(
        "orbit", "trajectory", "control", "imu", "sensors", "modes", "filter", "evaluation"
    )

    sensors = {}
    for name in sensors_table.data:
        table = sensors_table.table(name)
        kind = table.string("kind", "position", choices=("position", "rgnss"))
        sensors[name] = (
            _rgnss_sensor(name, table) if kind == "rgnss" else _position_sensor(name, table)
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
    almanacs = [s.almanac for s in sensors.values() if isinstance(s, RgnssSensor)]
    toa = float(almanacs[0].toa[0]) if almanacs else 0.0
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
        "inclination": math.radians(
            orbit.number("inclination_deg", 51.6, minimum=0.0, maximum=180.0)
        ),
        "raan": math.radians(orbit.number("raan_deg", 0.0)),
        "latitude_argument": math.radians(orbit.number("latitude_argument_deg", 0.0)),
        "gnss_start": toa + orbit.number("gnss_start_s", 0.0),
    }
    seed = evaluation.integer("seed", 0, minimum=0)
    for table in (root, orbit, traj, control, imu, filt, evaluation):
        table.check_unknown()
    try:
        return ApproachScenario(**fields), seed
    except ValueError as exc:
        raise ScenarioError(f"{root.path}: {exc}") from None


def _windows(table: TomlTable, field: str, width: int) -> tuple[tuple[float, ...], ...]:
    """Optional list of time windows ``[t_start, t_end(, value)]`` (s)."""
    if not table.has(field):
        return ()
    rows = table.array(field, (None, width))
    if np.any(rows[:, 1] <= rows[:, 0]):
        raise table.error(field, "each window needs t_start < t_end")
    return tuple(tuple(float(v) for v in row) for row in rows)


def _position_sensor(name: str, table: TomlTable) -> PositionSensor:
    return PositionSensor(
        name,
        table.number("sigma_m", positive=True),
        table.number("period_s", positive=True),
        table.boolean("optical", False),
        outages=_windows(table, "outages_s", 2),
        backup=table.string("backup", None) if table.has("backup") else None,
    )


def _rgnss_sensor(name: str, table: TomlTable) -> RgnssSensor:
    path = table.path.parent / table.string("almanac")
    try:
        almanac = parse_yuma(path.read_text(), source=str(path))
    except OSError as exc:
        raise table.error("almanac", f"cannot read {path}: {exc.strerror}") from None
    except AlmanacError as exc:
        raise table.error("almanac", str(exc)) from None
    mask = table.number("elevation_mask_deg", minimum=-90.0, maximum=89.0)
    common = {
        "code_sigma": table.number("code_sigma_m", positive=True),
        "phase_sigma": table.number("phase_sigma_m", positive=True),
        "cycle_slip_probability": table.number(
            "cycle_slip_probability", 0.0, minimum=0.0, maximum=1.0
        ),
        "cycle_slip_max": table.integer("cycle_slip_max", 10, minimum=1),
        "multipath_code_sigma": table.number("multipath_code_m", 0.0, minimum=0.0),
        "multipath_phase_sigma": table.number("multipath_phase_m", 0.0, minimum=0.0),
        "multipath_time_constant": table.number("multipath_time_constant_s", 60.0, positive=True),
    }

    def receiver(prefix: str) -> ReceiverModel:
        own = table.number(f"{prefix}_elevation_mask_deg", mask, minimum=-90.0, maximum=89.0)
        windows = _windows(table, f"{prefix}_obstructions", 3)
        return ReceiverModel(
            elevation_mask=math.radians(own),
            obstructions=tuple((a, b, math.radians(m)) for a, b, m in windows),
            **common,
        )

    solver = RelativeGnssConfig(
        code_sigma=common["code_sigma"],
        phase_sigma=common["phase_sigma"],
        ratio_threshold=table.number("ratio_threshold", minimum=1.0),
        min_success_rate=table.number("min_success_rate", minimum=0.0, maximum=0.999999),
    )
    return RgnssSensor(
        name,
        table.number("period_s", positive=True),
        almanac.healthy(),
        target_receiver=receiver("target"),
        chaser_receiver=receiver("chaser"),
        solver=solver,
        backup=table.string("backup", None) if table.has("backup") else None,
    )
