"""Photometric bands: the Sun's magnitude per band, simulated files and their inversion."""

import numpy as np
import pytest

from lightcurve import io
from lightcurve.cli import main
from lightcurve.photometry.bands import SUN_MAGNITUDES, band_offset, header_offset, sun_magnitude
from lightcurve.photometry.measurement import PhotometricModel
from lightcurve.photometry.render import SUN_MAGNITUDE
from lightcurve.photometry.simulate import simulate
from lightcurve.sky.ephemeris import CircularOrbit, Site, orbit_geometry
from shapes import get_library

SITE = Site(32.4434, -110.7881, 2790.0, "Mount Lemmon")


def test_the_sun_s_magnitudes_follow_the_absolute_ones_at_1_au():
    # Willmer (2018): M_V = 4.81 (Vega), 4.80 (AB); the distance modulus of 1 AU
    modulus = 5 * np.log10(1.495978707e11 / (10 * 3.0856775814913673e16))
    assert sun_magnitude("V", "vega") == pytest.approx(4.81 + modulus, abs=1e-3)
    assert sun_magnitude("V", "AB") == pytest.approx(4.80 + modulus, abs=1e-3)
    # a redder band is brighter in AB for the Sun's spectrum; the blue band fainter
    assert sun_magnitude("r", "ab") < sun_magnitude("g", "ab") < sun_magnitude("u", "ab")
    # every value is near the V magnitude of the measurement model (within the Sun's colours)
    assert all(abs(m - SUN_MAGNITUDE) < 2.0 for m in SUN_MAGNITUDES.values())
    assert band_offset("V", "vega") == pytest.approx(-0.02, abs=0.005)


def test_unknown_bands_and_systems_are_named():
    with pytest.raises(ValueError, match="no Sun magnitude for band 'R' in ab: known are"):
        sun_magnitude("R", "ab")
    with pytest.raises(ValueError, match="unknown magnitude system 'st'"):
        sun_magnitude("V", "st")


@pytest.fixture(scope="module")
def geometry():
    mjd = 60379.2 + np.arange(0.0, 300.0, 5.0) / 86400.0
    return orbit_geometry(CircularOrbit.geostationary(-100.0, mjd[0]), SITE, mjd, "geo")


def test_a_band_shifts_the_simulation_and_the_model_takes_it_back(geometry):
    shape = get_library().load("box")
    state = {"q0": np.array([0.1, 0.2, 0.3, 0.9]), "omega0": np.radians([0.5, 1.0, -0.3])}
    plain = simulate(geometry, shape, **state, seed=1)
    in_r = simulate(geometry, shape, **state, seed=1, band=("r", "ab"))
    offset = sun_magnitude("r", "ab") - SUN_MAGNITUDE
    assert np.allclose(in_r.magnitudes - plain.magnitudes, offset)
    assert in_r.meta["band"] == "r" and in_r.meta["magnitude_system"] == "ab"
    assert header_offset(in_r.meta) == pytest.approx(offset)
    # the measurement model sees the same magnitudes either way
    model_plain = PhotometricModel(plain, {"box": shape})
    model_r = PhotometricModel(in_r, {"box": shape})
    assert np.allclose(model_plain.magnitudes, model_r.magnitudes)


def test_simulate_command_writes_the_band(tmp_path, geometry):
    geo = tmp_path / "geo.csv"
    io.write(geometry, geo)
    out = tmp_path / "sim.csv"
    args = ["simulate", str(geo), "--shape", "box", "--q0", "0,0,0,1", "--omega0", "0.5,1,-0.3"]
    assert main([*args, "--band", "g", "--magnitude-system", "ab", "--out", str(out)]) == 0
    written = io.read(out)
    assert written.meta["band"] == "g"
    assert float(written.meta["sun_magnitude"]) == pytest.approx(sun_magnitude("g", "ab"))
    assert main([*args, "--band", "Q", "--out", str(tmp_path / "bad.csv")]) != 0
