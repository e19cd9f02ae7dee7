"""Earthshine against an independent surface integral over the visible Earth."""

import math

import numpy as np
import pytest

from lightcurve.photometry.earthshine import (
    EARTH_RADIUS_M,
    earth_cap_quadrature,
    earthshine_flux,
)
from lightcurve.photometry.render import Renderer
from shapes import Material, primitives


def plate_irradiance_by_surface(altitude_m: float, elevation: float, albedo: float) -> float:
    """Irradiance (in units of the Sun's) on a plate facing the nadir, integrated over the
    Earth's surface: ``∫ (A/π) max(0, m·ŝ) cos ε cos ι / d² dA`` over the points the plate
    sees, on a midpoint grid in the polar angle from the sub-object point and the azimuth,
    refined once by Richardson extrapolation (error ∝ h² at the terminator's kink)."""
    r = EARTH_RADIUS_M + altitude_m
    gamma_max = math.acos(EARTH_RADIUS_M / r)
    # object on +z; the Sun at the elevation above the object's local horizontal, in x–z
    sun = np.array([math.cos(elevation), 0.0, math.sin(elevation)])

    def integral(n: int) -> float:
        g = (np.arange(n) + 0.5) * gamma_max / n
        b = (np.arange(2 * n) + 0.5) * math.pi / n
        g, b = np.meshgrid(g, b, indexing="ij")
        m = np.stack([np.sin(g) * np.cos(b), np.sin(g) * np.sin(b), np.cos(g)], axis=-1)
        to_object = np.array([0.0, 0.0, r]) - EARTH_RADIUS_M * m
        d = np.linalg.norm(to_object, axis=-1)
        cos_e = np.sum(m * to_object, axis=-1) / d
        cos_i = (r - EARTH_RADIUS_M * m[..., 2]) / d  # plate normal −z, towards the point
        lit = np.clip(m @ sun, 0.0, None)
        f = albedo / math.pi * lit * np.clip(cos_e, 0, None) * cos_i / d**2
        area = EARTH_RADIUS_M**2 * np.sin(g) * (gamma_max / n) * (math.pi / n)
        return float(np.sum(f * area))

    coarse, fine = integral(300), integral(600)
    return fine + (fine - coarse) / 3.0


@pytest.mark.parametrize("altitude_km", [300.0, 550.0, 20_200.0, 35_786.0])
@pytest.mark.parametrize("elevation_deg", [-50.0, -20.0, 0.0, 10.0, 90.0])
def test_plate_facing_nadir_matches_the_surface_integral(altitude_km, elevation_deg):
    albedo = 0.3
    position = np.array([0.0, 0.0, EARTH_RADIUS_M + altitude_km * 1e3])
    elevation = math.radians(elevation_deg)
    sun = 1.5e11 * np.array([math.cos(elevation), 0.0, math.sin(elevation)])
    directions, weights = earth_cap_quadrature(position, sun, albedo=albedo)
    quadrature = float(np.sum(weights * np.clip(directions @ [0.0, 0.0, -1.0], 0.0, None)))
    reference = plate_irradiance_by_surface(altitude_km * 1e3, elevation, albedo)
    if reference < 1e-12:  # the sunlit Earth is below the plate's view: nothing to compare
        assert quadrature < 1e-9
    else:
        assert quadrature == pytest.approx(reference, rel=0.01)


def test_directions_stay_inside_the_cap_and_weights_are_non_negative():
    rng = np.random.default_rng(0)
    position = rng.normal(size=(50, 3))
    position *= (EARTH_RADIUS_M + rng.uniform(3e5, 4e7, 50) / 1.0)[:, None] / np.linalg.norm(
        position, axis=1
    )[:, None]
    sun = rng.normal(size=(50, 3))
    directions, weights = earth_cap_quadrature(position, sun)
    nadir = -position / np.linalg.norm(position, axis=1)[:, None]
    cos_rho = np.sqrt(1 - (EARTH_RADIUS_M / np.linalg.norm(position, axis=1)) ** 2)
    assert np.allclose(np.linalg.norm(directions, axis=-1), 1.0)
    assert np.all(np.einsum("ekc,ec->ek", directions, nadir) >= cos_rho[:, None] - 1e-9)
    assert np.all(weights >= 0.0)


def test_a_full_earth_lights_a_sphere_as_the_solid_angle_says():
    """Sun behind the object (full Earth seen): a Lambertian sphere's earthshine is at most
    the albedo times the cap's solid-angle share, and more than none."""
    position = np.array([[0.0, 0.0, EARTH_RADIUS_M + 5.5e5]])
    sun = np.array([[0.0, 0.0, 1.5e11]])
    _, weights = earth_cap_quadrature(position, sun, albedo=0.3)
    rho = math.asin(EARTH_RADIUS_M / np.linalg.norm(position))
    solid_angle = 2 * math.pi * (1 - math.cos(rho))
    assert 0.0 < weights.sum() < 0.3 / math.pi * solid_angle


def test_earthshine_of_a_plate_through_the_renderer():
    """A Lambertian plate facing the nadir: the renderer's flux summed over the nodes
    equals the irradiance times the plate's reflection towards a zenith observer."""
    plate = primitives.plate(1.0, 1.0, materials=Material("lambert", {"rd": 0.5}))  # front +z
    renderer = Renderer(plate, shadows="none")
    position = np.array([[0.0, 0.0, EARTH_RADIUS_M + 5.5e5]])
    sun = np.array([[1.5e11, 0.0, 0.0]])  # Sun on the object's horizon
    observer = np.array([[0.0, 0.0, -4e5]])  # below it: sees the Earth-facing side
    # body +z to inertial −z: a half turn about x
    q = np.array([[1.0, 0.0, 0.0, 0.0]])
    flux = earthshine_flux(renderer, q, observer, position, sun)
    directions, weights = earth_cap_quadrature(position, sun)
    irradiance = float(np.sum(weights * np.clip(directions @ [0.0, 0.0, -1.0], 0.0, None)))
    # Lambertian plate of unit area seen face-on from d: F = ρ/π · E · cos e / d²
    expected = 0.5 / math.pi * irradiance * 1.0 / 4e5**2
    assert flux[0] == pytest.approx(expected, rel=1e-6)


def test_bad_inputs():
    with pytest.raises(ValueError, match="outside the Earth"):
        earth_cap_quadrature([0.0, 0.0, 1e6], [1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="albedo"):
        earth_cap_quadrature([0.0, 0.0, 1e7], [1.0, 0.0, 0.0], albedo=1.5)


def test_simulate_adds_the_earth_s_light_and_its_share(tmp_path):
    from lightcurve import io
    from lightcurve.cli import main
    from lightcurve.photometry.simulate import simulate
    from lightcurve.sky.ephemeris import CircularOrbit, Site, orbit_geometry
    from shapes import get_library

    site = Site(32.4434, -110.7881, 2790.0, "Mount Lemmon")
    mjd = 60379.2 + np.arange(0.0, 600.0, 10.0) / 86400.0
    geometry = orbit_geometry(CircularOrbit.geostationary(-100.0, mjd[0]), site, mjd, "geo")
    state = {"q0": np.array([0.1, 0.2, 0.3, 0.9]), "omega0": np.radians([0.5, 1.0, -0.3])}
    box = get_library().load("box")
    plain = simulate(geometry, box, **state)  # GEO: above the altitude where auto adds it
    assert "earthshine_fraction" not in plain.table and plain.meta["earthshine"] == "off"
    lit = simulate(geometry, box, **state, earthshine="on")
    assert lit.meta["earthshine"].startswith("lambertian")
    share = lit.table["earthshine_fraction"].to_numpy()
    assert np.all((share > 0.0) & (share < 0.2))
    # the magnitudes brighten by exactly the share
    np.testing.assert_allclose(
        plain.magnitudes - lit.magnitudes, -2.5 * np.log10(1.0 - share), atol=1e-9
    )
    path = tmp_path / "geo.csv"
    io.write(geometry, path)
    out = tmp_path / "sim.csv"
    argv = ["simulate", str(path), "--shape", "box", "--q0", "0,0,0,1"]
    assert main([*argv, "--omega0", "0.5,1,-0.3", "--earthshine", "on", "--out", str(out)]) == 0
    assert "earthshine_fraction" in io.read(out).table


def test_auto_adds_earthshine_below_the_stated_altitude_only():
    from lightcurve.photometry.earthshine import EARTHSHINE_ALTITUDE_KM, earthshine_applies

    # the altitude where a full Earth gives a nadir plate 1 % of the Sun's irradiance
    r = EARTH_RADIUS_M + EARTHSHINE_ALTITUDE_KM * 1e3
    assert 0.29 * (EARTH_RADIUS_M / r) ** 2 == pytest.approx(0.01, rel=2e-3)
    low = np.array([[EARTH_RADIUS_M + 5.5e5, 0.0, 0.0]])
    geo = np.array([[4.2164e7, 0.0, 0.0]])
    assert earthshine_applies("auto", low) and not earthshine_applies("auto", geo)
    assert earthshine_applies("auto", np.vstack([geo, low]))  # one file, rendered alike
    assert earthshine_applies("on", geo) and not earthshine_applies("off", low)
    assert not earthshine_applies("auto", None)
    with pytest.raises(ValueError, match="obj_x obj_y obj_z"):
        earthshine_applies("on", None)
    with pytest.raises(ValueError, match="auto, on, off"):
        earthshine_applies("yes", low)


def test_a_sun_tracking_array_keeps_its_sun_pose_under_the_earth_s_light():
    """The articulated renderer lit from the Earth's directions poses its joints by the Sun:
    its earthshine equals that of the rigid shape posed at the Sun-tracking angles."""
    from lightcurve.photometry.articulated import ArticulatedRenderer
    from shapes import get_library

    rng = np.random.default_rng(3)
    starlink = get_library().load("starlink_v1_5", articulated=True)
    renderer = ArticulatedRenderer(starlink, shadows="none")
    n = 20
    position = rng.normal(size=(n, 3))
    position *= (EARTH_RADIUS_M + 5.5e5) / np.linalg.norm(position, axis=1)[:, None]
    sun = 1.5e11 * rng.normal(size=(n, 3))
    observer = -position / np.linalg.norm(position, axis=1)[:, None] * 1e6 + rng.normal(
        scale=3e5, size=(n, 3)
    )
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    articulated = earthshine_flux(renderer, q, observer, position, sun)
    angles = renderer.joint_angles(q, sun)[0]
    rigid = np.array(
        [
            earthshine_flux(
                Renderer(starlink.posed(starlink.moving_rotations(_sun_body(q[i], sun[i])))),
                q[i : i + 1],
                observer[i : i + 1],
                position[i : i + 1],
                sun[i : i + 1],
            )[0]
            for i in range(n)
        ]
    )
    assert np.ptp(angles) > 10.0  # the array does turn between epochs
    assert np.any(articulated > 0.0)
    np.testing.assert_allclose(articulated, rigid, rtol=1e-9, atol=1e-15)


def _sun_body(q, sun):
    from filters.attitude import rotate

    return rotate(q, sun)
