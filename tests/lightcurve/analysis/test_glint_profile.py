"""Glints under a known attitude profile: panel normals in the body frame."""

import json
import math

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from filters.attitude import attitude_angle, rotate
from lightcurve import io
from lightcurve.analysis.glint.profile import group_panels, profile_attitudes_at
from lightcurve.cli import main
from lightcurve.photometry.profiles import offset_quaternion, profile_attitude
from lightcurve.photometry.simulate import GaussianNoise, simulate
from lightcurve.sky.ephemeris import CircularOrbit, Site, orbit_geometry
from lightcurve.sky.geometry import phase_angle_bisector
from shapes import primitives

MOUNT_LEMMON = Site(32.4434, -110.7881, 2790.0, "Mount Lemmon")
OFFSET = np.array([3.0, -4.0, 6.0])


def _angle_deg(a, b):
    return math.degrees(math.acos(float(np.clip(np.dot(a, b), -1.0, 1.0))))


@pytest.fixture(scope="module")
def window():
    """A GEO slot seen from Mount Lemmon, the night of 2024-01-15 every two minutes."""
    mjd = 60324.0 + np.arange(0.0, 15 * 3600.0, 120.0) / 86400.0
    return orbit_geometry(CircularOrbit.geostationary(-100.0, mjd[0]), MOUNT_LEMMON, mjd, "geo")


@pytest.fixture(scope="module")
def flashing(window, tmp_path_factory):
    """A nadir-pointing box-wing (offset 3°, −4°, 6°) whose fixed arrays face the body-frame
    bisector a third into the night: the box-wing's mesh turned so that the array normal is
    there (the arrays' mirror lobe, about 2° wide, makes a half-hour flash of 6 mag)."""
    q = profile_attitude(
        "nadir",
        position=window.object_positions,
        velocity=window.object_velocities,
        offset=offset_quaternion(OFFSET),
    )
    bisector = phase_angle_bisector(window.sun_vectors, window.observer_vectors)
    normal = np.asarray(rotate(q, bisector))[len(window) // 3]
    base = primitives.box_wing()
    turn, _ = Rotation.align_vectors(normal[None], np.array([base.provenance["array_normal"]]))
    m = turn.as_matrix()
    shape = base.replace(
        vertices=base.vertices @ m.T,
        center_of_mass=m @ base.center_of_mass,
        inertia=m @ base.inertia @ m.T,
    )
    sim = simulate(
        window,
        shape,
        noise=GaussianNoise(0.02),
        seed=3,
        profile="nadir",
        offset_deg=OFFSET,
        shadows="none",
    )
    path = tmp_path_factory.mktemp("glint_profile") / "nadir.csv"
    io.write(sim, path)
    return path, normal


def test_glint_command_gives_the_body_normal_of_a_fixed_panel(flashing, tmp_path, capsys):
    path, normal = flashing
    out = tmp_path / "with_offset"
    args = ["glint", str(path), "--profile", "nadir", "--out", str(out)]
    assert main([*args, "--offset-deg", "3,-4,6"]) == 0
    assert "panel 0 normal (body, --profile nadir)" in capsys.readouterr().out
    summary = json.loads((out / "glints.json").read_text())
    assert summary["attitude_profile"] == {
        "profile": "nadir",
        "offset_deg": [3.0, -4.0, 6.0],
        "yaw_steering": False,
    }
    assert _angle_deg(summary["normal_body"], normal) < 1.0
    assert math.isclose(np.linalg.norm(summary["normal_body"]), 1.0, rel_tol=1e-9)
    panel = summary["normal_body_panels"][0]
    assert panel["normal_body"] == summary["normal_body"]
    assert summary["normal_body_spread_deg"] == panel["spread_deg"] <= 5.0
    brightest = int(np.argmax([g["amplitude_mag"] for g in summary["glints"]]))
    assert brightest in panel["glints"] and summary["glints"][brightest]["panel"] == 0
    table = pd.read_csv(out / "glints.csv")
    row = table.iloc[brightest]
    assert _angle_deg(row[["normal_body_x", "normal_body_y", "normal_body_z"]], normal) < 1.5
    # Without its offset the profile turns the same glint elsewhere in the body.
    assert main([*args, "--out", str(tmp_path / "no_offset")]) == 0
    plain = json.loads((tmp_path / "no_offset" / "glints.json").read_text())
    assert _angle_deg(plain["normal_body"], normal) > 3.0


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--offset-deg", "1,2,3"], "go with --profile"),
        (["--profile", "sun-pointing", "--yaw-steering"], "applies to --profile nadir only"),
        (["--profile", "nadir", "--normal", "--frame", "body"], "not with --frame body"),
        (["--profile", "inertial", "--panel-tolerance", "0"], "--panel-tolerance"),
    ],
)
def test_glint_profile_option_errors(flashing, capsys, extra, message):
    assert main(["glint", str(flashing[0]), *extra]) != 0
    assert message in capsys.readouterr().err


def test_nadir_profile_needs_the_object_columns(flashing, tmp_path, capsys):
    table = pd.read_csv(flashing[0], comment="#")
    bare = tmp_path / "bare.csv"
    table.drop(columns=[c for c in table if c.startswith("obj_")]).to_csv(bare, index=False)
    assert main(["glint", str(bare), "--profile", "nadir"]) != 0
    err = capsys.readouterr().err
    assert "bare.csv" in err and "obj_x" in err


def test_profile_attitudes_between_epochs_match_the_profile_there(window):
    """Attitudes interpolated to the odd samples from the even ones (4 min apart) agree with
    the profile evaluated there: to rounding for the nadir frame, which turns uniformly, and
    within 0.05° where the turn is not uniform (yaw steering, Sun-pointing)."""
    every_other = window.table.iloc[::2].reset_index(drop=True)
    coarse = type(window)(every_other, dict(window.meta))
    odd = window.times[1:-1:2]
    for profile, yaw, limit in (
        ("nadir", False, 1e-6),
        ("nadir", True, 0.05),
        ("sun-pointing", False, 0.05),
    ):
        q = profile_attitudes_at(coarse, profile, odd, offset_deg=OFFSET, yaw_steering=yaw)
        exact = profile_attitude(
            profile,
            position=window.object_positions,
            velocity=window.object_velocities,
            sun=window.sun_vectors,
            yaw_steering=yaw,
            offset=offset_quaternion(OFFSET),
        )[1:-1:2]
        assert np.degrees(np.max(attitude_angle(q, exact))) < limit
    with pytest.raises(ValueError, match="outside the file's span"):
        profile_attitudes_at(coarse, "inertial", [coarse.times[-1] + 60.0])


def test_glints_group_into_panels_brightest_first():
    rng = np.random.default_rng(0)
    a, b = np.array([0.0, 0.0, 1.0]), np.array([math.sin(0.5), 0.0, math.cos(0.5)])
    directions = np.array([a, b, a, b, a]) + rng.normal(0.0, 0.01, (5, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    panels = group_panels(directions, [0.1, 3.0, 0.2, 0.5, 0.3], tolerance_deg=5.0)
    assert [sorted(p.tolist()) for p in panels] == [[1, 3], [0, 2, 4]]
    assert len(group_panels(directions, np.ones(5), tolerance_deg=60.0)) == 1
    with pytest.raises(ValueError, match="tolerance_deg"):
        group_panels(directions, np.ones(5), tolerance_deg=0.0)
