"""Observing conditions: the CCD equation by hand, extinction, scintillation, saturation."""

import math

import numpy as np
import pytest
from scipy.integrate import quad

from benchmarks.noise import placeholder_geometry
from lightcurve import io
from lightcurve.cli import main
from lightcurve.io.observations import Observations, validate_table
from lightcurve.photometry.conditions import (
    ObservingConditions,
    load_conditions,
    scintillation_sigma,
    sky_brightness,
)
from lightcurve.photometry.noise import (
    CCDNoise,
    GaussianNoise,
    ObservingNoise,
    observation_elevation,
)
from lightcurve.photometry.psf import SeeingProfile
from lightcurve.sky.satellite_geometry import from_horizontal
from lightcurve.sky.sites import Site

MOUNT_LEMMON = Site(32.4434, -110.7881, 2790.0, "Mount Lemmon")


def constant_source(elevation_deg, site=MOUNT_LEMMON, **columns):
    """A geometry table of n rows with the given elevations (vectors are placeholders)."""
    return placeholder_geometry(elevation_deg, site, "constant.csv", **columns)


def test_snr_of_a_star_matches_the_ccd_equation_worked_by_hand():
    """V = 12 at 45° elevation, 0.5 m telescope, 10 s: Howell's eq. 4.4 written out."""
    conditions = load_conditions(
        None,
        {
            "telescope": {"aperture_m": 0.5, "obstruction_m": 0.2, "throughput": 0.5},
            "detector": {
                "pixel_scale_arcsec": 1.0,
                "read_noise_e": 10.0,
                "gain_e_per_adu": 1.5,
                "dark_current_e_per_s": 0.1,
            },
            "site": {
                "extinction_mag_per_airmass": 0.2,
                "seeing_fwhm_arcsec": 2.0,
                "seeing_profile": "gaussian",
                "scintillation_coefficient": 1.5,
            },
            "sky": {"brightness_mag_arcsec2": 21.0, "airmass_brightening": False},
            "photometry": {
                "zero_point_mag": 24.86,
                "aperture_radius_arcsec": 4.0,
                "sky_annulus_px": 300.0,
            },
        },
    )
    # By hand. Airmass: Kasten & Young (1989) at 45°.
    x = 1.0 / (math.sin(math.radians(45.0)) + 0.50572 * (45.0 + 6.07995) ** -1.6364)
    assert x == pytest.approx(1.41, abs=0.01)
    area = math.pi / 4.0 * (0.5**2 - 0.2**2)  # m²
    photons_v0 = 10 ** (0.4 * 24.86)  # photons s⁻¹ m⁻² at V = 0 above the atmosphere
    electrons_total = photons_v0 * 10 ** (-0.4 * (12.0 + 0.2 * x)) * area * 0.5 * 10.0
    sigma_psf = 2.0 * x**0.6 / (2.0 * math.sqrt(2.0 * math.log(2.0)))  # arcsec
    n_star = electrons_total * (1.0 - math.exp(-(4.0**2) / (2.0 * sigma_psf**2)))
    n_sky = photons_v0 * 10 ** (-0.4 * 21.0) * area * 0.5 * 10.0 * 1.0**2  # per pixel
    n_dark = 0.1 * 10.0
    n_pix = math.pi * 4.0**2
    scint_var = 1e-5 * 1.5**2 * 0.5 ** (-4.0 / 3.0) / 10.0 * x**3 * math.exp(-2 * 2790.0 / 8000)
    noise = math.sqrt(
        n_star
        + scint_var * n_star**2
        + n_pix * (1.0 + n_pix / 300.0) * (n_sky + n_dark + 10.0**2 + 1.5**2 / 12.0)
    )
    snr_by_hand = n_star / noise
    budget = conditions.budget(np.array([12.0]), np.array([45.0]), 10.0, 2790.0)
    assert budget.snr[0] == pytest.approx(snr_by_hand, rel=0.01)
    assert budget.source_e[0] == pytest.approx(n_star, rel=1e-9)
    # The simulated spread of the measured magnitudes agrees with this SNR.
    geometry = constant_source(np.full(10_000, 45.0), exposure_s=np.full(10_000, 10.0))
    measured = ObservingNoise(conditions).measure(
        np.full(10_000, 12.0), geometry, np.random.default_rng(11)
    )
    flux = 10 ** (-0.4 * (measured.magnitude - 12.0))
    assert flux.mean() / flux.std() == pytest.approx(snr_by_hand, rel=0.03)
    assert np.median(measured.error) == pytest.approx(2.5 / math.log(10) / snr_by_hand, rel=0.02)


def test_sky_brightening_and_moffat_losses_by_hand():
    """Krisciunas & Schaefer sky and a Moffat aperture fraction at 30° elevation."""
    conditions = ObservingConditions()
    budget = conditions.budget(np.array([10.0]), np.array([30.0]), 1.0, 2000.0)
    z = math.radians(60.0)
    path = (1.0 - 0.96 * math.sin(z) ** 2) ** -0.5
    mu = 21.0 + 0.2 * (path - 1.0) - 2.5 * math.log10(path)
    area = math.pi / 4.0 * (0.5**2 - 0.2**2)
    assert budget.sky_e[0] == pytest.approx(10 ** (-0.4 * (mu - 24.86)) * area * 0.5, rel=1e-9)
    x = 1.0 / (0.5 + 0.50572 * 36.07995**-1.6364)
    beta = 4.765
    alpha = 2.0 * x**0.6 / (2.0 * math.sqrt(2 ** (1 / beta) - 1.0))
    assert budget.aperture_fraction[0] == pytest.approx(
        1.0 - (1.0 + (3.0 / alpha) ** 2) ** (1 - beta), rel=1e-9
    )
    assert sky_brightness(21.0, 0.2, np.array([90.0]))[0] == pytest.approx(21.0)


@pytest.mark.parametrize("kind", ["gaussian", "moffat"])
def test_seeing_profiles_against_numerical_integration(kind):
    profile = SeeingProfile(kind, 3.0)
    fwhm = 2.2
    peak = profile.peak_intensity(fwhm)

    def intensity(r):  # I(r)/F from the enclosed fraction's derivative, f'(r) / (2π r)
        h = 1e-6
        return (
            (profile.enclosed_fraction(r + h, fwhm) - profile.enclosed_fraction(r - h, fwhm))
            / (2 * h)
            / (2 * math.pi * r)
        )

    assert intensity(fwhm / 2) == pytest.approx(0.5 * peak, rel=1e-5)  # the FWHM is right
    assert intensity(1e-3) == pytest.approx(peak, rel=1e-4)
    assert float(profile.enclosed_fraction(200.0, fwhm)) == pytest.approx(1.0, abs=1e-6)
    # Clipping at a level: the loss is the integral of (I − I_s) where I > I_s.
    flux, radius = 1e6, 3.0
    for level in (1e3, 1e4, 5e4):
        loss = profile.saturation_loss(np.array([flux]), fwhm, radius, np.array([level]))[0]
        numeric = quad(
            lambda r, level=level: max(flux * intensity(r) - level, 0.0) * 2 * math.pi * r,
            1e-4,
            radius,
            limit=200,
        )[0]
        assert loss == pytest.approx(numeric, rel=1e-4)
    assert profile.saturation_loss(np.array([flux]), fwhm, radius, np.array([1e9]))[0] == 0.0


def test_scintillation_against_young_1967():
    """At the zenith and C_Y = 1, Osborn's eq. 7 is Young's 0.09 D_cm^(-2/3) (2t)^(-1/2)."""
    young = 0.09 * 50.0 ** (-2 / 3) * math.exp(-2790.0 / 8000.0) / math.sqrt(2 * 5.0)
    ours = scintillation_sigma(0.5, 5.0, 1.0, 2790.0, 1.0)
    assert ours == pytest.approx(young, rel=0.08)  # 10⁻⁵ rounds Young's 0.09²·100^(−4/3)/2
    # X^(3/2), t^(-1/2) and C_Y scalings.
    assert scintillation_sigma(0.5, 5.0, 2.0, 2790.0, 1.5) / ours == pytest.approx(1.5 * 2**1.5)
    assert scintillation_sigma(0.5, 20.0, 1.0, 2790.0, 1.0) / ours == pytest.approx(0.5)


def test_mean_of_constant_source_is_the_extinction_corrected_magnitude():
    """10⁴ exposures of a V = 11 source between 20° and 90° elevation (seed 5)."""
    n = 10_000
    elevation = np.random.default_rng(1).uniform(20.0, 90.0, n)
    geometry = constant_source(elevation)
    noise = ObservingNoise(load_conditions("half_metre"))
    measured = noise.measure(np.full(n, 11.0), geometry, np.random.default_rng(5))
    mags = measured.magnitude
    assert np.all(np.isfinite(mags)) and not measured.columns["saturated"].any()
    standard_error = mags.std() / math.sqrt(n)
    assert abs(mags.mean() - 11.0) < 3 * standard_error
    # The flux is unbiased; the magnitude only by the second-order term (2.5/ln 10) σ_F²/2.
    flux = 10 ** (-0.4 * (mags - 11.0))
    assert abs(flux.mean() - 1.0) < 3 * flux.std() / math.sqrt(n)
    bias = np.mean(0.5 * (measured.error / (2.5 / math.log(10))) ** 2 * 2.5 / math.log(10))
    assert abs(mags.mean() - bias - 11.0) < 2 * standard_error
    extinction = measured.columns["extinction_mag"]
    np.testing.assert_allclose(extinction, 0.2 * measured.columns["airmass"])
    # Without the correction the magnitudes are those seen through the atmosphere.
    raw = ObservingNoise(load_conditions("half_metre", ["photometry.extinction_corrected=false"]))
    observed = raw.measure(np.full(n, 11.0), geometry, np.random.default_rng(5)).magnitude
    np.testing.assert_allclose(observed - extinction, mags, atol=1e-12)
    slope, _ = np.polyfit(measured.columns["airmass"], observed, 1)
    assert slope == pytest.approx(0.2, abs=0.02)
    # The reported errors describe the scatter, normalised residuals are unit normal.
    pull = (mags - 11.0) / measured.error
    assert pull.std() == pytest.approx(1.0, abs=0.03)


def test_saturated_points_are_flagged_and_too_faint():
    conditions = load_conditions(None, ["site.scintillation_coefficient=0"])
    magnitude = np.linspace(4.0, 11.0, 141)
    geometry = constant_source(np.full(magnitude.size, 50.0))
    measured = ObservingNoise(conditions).measure(magnitude, geometry, np.random.default_rng(2))
    saturated = measured.columns["saturated"]
    # By hand: peak pixel = total electrons · (β−1)/(π α²) · p² + sky + dark ≥ 65535 · 1.5.
    x = 1.0 / (math.sin(math.radians(50.0)) + 0.50572 * 56.07995**-1.6364)
    area = math.pi / 4.0 * (0.5**2 - 0.2**2)
    total = 10 ** (-0.4 * (magnitude + 0.2 * x - 24.86)) * area * 0.5
    alpha = 2.0 * x**0.6 / (2.0 * math.sqrt(2 ** (1 / 4.765) - 1.0))
    peak = total * 3.765 / (math.pi * alpha**2)
    level = min(1e5, 1.5 * 65535) - 0.1
    sky = conditions.budget(magnitude[:1], np.array([50.0]), 1.0, 0.0).sky_e[0]
    np.testing.assert_array_equal(saturated, peak + sky >= level)
    assert 0 < saturated.sum() < magnitude.size
    # Clipped light is lost: saturated magnitudes are too faint, more so the brighter.
    offset = measured.magnitude - magnitude
    deep = peak + sky >= 2 * level
    assert deep.sum() > 20 and np.all(offset[deep] > 5 * measured.error[deep])
    assert np.all(np.diff(offset[deep]) < 0)
    assert np.all(np.abs(offset[~saturated]) < 5 * measured.error[~saturated])


def test_elevation_from_the_site_in_the_header():
    site = Site(32.4434, -110.7881, 2790.0, "Mount Lemmon")
    rng = np.random.default_rng(3)
    mjd = 60379.2 + np.arange(50) / 1440.0
    elevation, azimuth = rng.uniform(5.0, 89.0, 50), rng.uniform(0.0, 360.0, 50)
    geometry = from_horizontal(site, mjd, elevation, azimuth, rng.uniform(500.0, 4e4, 50))
    table = geometry.table().drop(columns=["elevation_deg", "azimuth_deg", "airmass"])
    bare = Observations(
        validate_table(table, "g.csv", {"site": site.label}, require_magnitudes=False),
        {"site": site.label},
        "g.csv",
    )
    np.testing.assert_allclose(observation_elevation(bare), elevation, atol=1e-7)
    # The noise model takes the elevation either way, with the same draws.
    full = Observations(
        validate_table(geometry.table(), "g.csv", {}, require_magnitudes=False), {}, "g.csv"
    )
    noise = ObservingNoise(load_conditions(None, ["site.altitude_m=2790"]))
    a = noise.measure(np.full(50, 11.0), bare, np.random.default_rng(4))
    b = noise.measure(np.full(50, 11.0), full, np.random.default_rng(4))
    np.testing.assert_allclose(a.magnitude, b.magnitude, atol=1e-9)
    assert "elevation_deg" in a.columns and "elevation_deg" not in b.columns
    # A bare observatory name in the header works too (the Starlink data sets write it).
    named = Observations(bare.table, {"site": "Mount Lemmon"}, "g.csv")
    np.testing.assert_allclose(observation_elevation(named), elevation, atol=1e-3)


def test_clear_errors():
    noise = ObservingNoise()
    no_site = constant_source(np.full(3, 40.0), site=None).table.drop(columns="elevation_deg")
    geometry = Observations(no_site, {}, "geo.csv")
    with pytest.raises(ValueError, match=r"geo.csv: .*elevation_deg.*lightcurve geometry"):
        noise.measure(np.full(3, 10.0), geometry, np.random.default_rng(0))
    with pytest.raises(ValueError, match=r"constant.csv, row 2: .*below the horizon"):
        noise.measure(np.full(3, 10.0), constant_source([30.0, -1.0, 20.0]), None)
    with pytest.raises(ValueError, match=r"altitude_m"):
        noise.measure(np.full(2, 10.0), constant_source([30.0, 40.0], site=None), None)
    zero = constant_source([30.0, 40.0], exposure_s=[1.0, 0.0])
    with pytest.raises(ValueError, match=r"row 2, column 'exposure_s': exposure must be > 0"):
        noise.measure(np.full(2, 10.0), zero, None)
    asteroid = Observations(no_site, {"site": MOUNT_LEMMON.label, "frame": "ecliptic J2000"})
    with pytest.raises(ValueError, match="frame"):
        noise.measure(np.full(3, 10.0), asteroid, None)


def test_conditions_files_and_overrides(tmp_path):
    assert load_conditions("half_metre") == ObservingConditions() == load_conditions()
    path = tmp_path / "scope.toml"
    path.write_text(
        "[site]\nseeing_fwhm_arcsec = 1.2\naltitude_m = 2400\n[sky]\nairmass_brightening = false\n"
    )
    conditions = load_conditions(
        path, ["site.seeing_fwhm_arcsec=1.6", "site.seeing_profile=gaussian"]
    )
    assert conditions.site.seeing_fwhm_arcsec == 1.6 and conditions.site.altitude_m == 2400.0
    assert conditions.site.seeing_profile == "gaussian" and not conditions.sky.airmass_brightening
    assert conditions.telescope.aperture_m == 0.5  # the rest from the defaults
    for text, message in (
        ("[detector]\nread_noise_e = -3\n", r"scope.toml: \[detector\] read_noise_e: must be >= 0"),
        ("[detector]\nread_noise = 3\n", r"did you mean 'read_noise_e'"),
        ("[site\n", "invalid TOML"),
    ):
        path.write_text(text)
        with pytest.raises(ValueError, match=message):
            load_conditions(path)
    with pytest.raises(ValueError, match=r"--condition photometry.saturated: must be one of"):
        load_conditions(None, ["photometry.saturated=keep"])
    with pytest.raises(ValueError, match=r"must be a number"):
        load_conditions(None, ["telescope.aperture_m=big"])
    with pytest.raises(FileNotFoundError, match="known: half_metre"):
        load_conditions("two_metre")


def test_previous_noise_models_unchanged():
    """`measure` of the Gaussian and CCD models draws exactly what `apply` draws."""
    geometry = constant_source(np.full(500, 40.0), exposure_s=np.full(500, 2.0))
    magnitude = np.linspace(9.0, 15.0, 500)
    for model in (GaussianNoise(0.03), CCDNoise(aperture_m=0.4)):
        measured = model.measure(magnitude, geometry, np.random.default_rng(7))
        applied = model.apply(magnitude, np.full(500, 2.0), np.random.default_rng(7))
        np.testing.assert_array_equal(measured.magnitude, applied[0])
        np.testing.assert_array_equal(measured.error, applied[1])
        assert not measured.columns


def test_simulate_command_with_conditions(tmp_path, capsys):
    geo, out = tmp_path / "geo.csv", tmp_path / "sim.csv"
    common = ["--shape", "box_wing", "--q0", "0,0,0,1", "--omega0", "0.5,1,-0.3"]
    geometry_args = ["geometry", "--start", "2024-03-10T04:48:00", "--duration", "120"]
    assert main([*geometry_args, "--cadence", "5", "--geo", "-100", "--out", str(geo)]) == 0
    args = ["simulate", str(geo), *common, "--conditions", "half_metre", "--out", str(out)]
    assert main([*args, "--condition", "photometry.exposure_s=3", "--seed", "4"]) == 0
    sim = io.read(out)
    for column in ("extinction_mag", "saturated", "elevation_deg", "airmass"):
        assert column in sim.table
    assert sim.table["saturated"].dtype == bool
    assert sim.meta["noise"].startswith("conditions telescope.aperture_m=0.5")
    assert "photometry.exposure_s=3.0" in sim.meta["noise"]
    # Saturating everything: flagged by default, dropped on request (and counted).
    bright = ["--condition", "detector.full_well_e=10", "--condition", "detector.adc_max_adu=5"]
    assert main([*args, *bright]) == 0
    assert io.read(out).table["saturated"].all()
    assert "saturated points flagged" in capsys.readouterr().out
    assert main([*args, *bright, "--condition", "photometry.saturated=drop"]) == 2
    assert "dropped as saturated" in capsys.readouterr().err
    assert (
        main(
            [
                *args[:-4],
                "--noise-mag",
                "0.1",
                "--condition",
                "site.seeing_fwhm_arcsec=1",
                "--out",
                str(out),
            ]
        )
        == 2
    )
    assert "--condition" in capsys.readouterr().err


def test_circular_orbit_geometry_has_the_horizon_columns():
    """The circular-orbit route writes WGS84 elevations and airmasses, never below the horizon."""
    from lightcurve.sky.ephemeris import CircularOrbit, orbit_geometry
    from lightcurve.sky.topocentric import airmass, horizontal_from_gcrs

    mjd = 60379.1 + np.arange(600) * 60.0 / 86400.0
    orbit = CircularOrbit(7000.0, 51.6, 20.0, 0.0, mjd[0])
    geometry = orbit_geometry(orbit, MOUNT_LEMMON, mjd, "leo", None, None)
    table = geometry.table
    assert 0 < len(table) < mjd.size and np.all(table["elevation_deg"] > 0)
    elevation, _, distance = horizontal_from_gcrs(
        MOUNT_LEMMON, geometry.mjd, -geometry.observer_vectors / 1e3
    )
    np.testing.assert_allclose(table["elevation_deg"], elevation, atol=1e-9)
    np.testing.assert_allclose(table["range_km"], distance, rtol=1e-12)
    np.testing.assert_allclose(table["airmass"], airmass(elevation))
