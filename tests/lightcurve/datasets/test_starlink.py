"""Starlink v1.5 end-to-end forward-model check on the Pomenis observations."""

from importlib import resources

import numpy as np

from filters.attitude import attitude_matrix
from lightcurve.datasets.starlink import (
    CHASSIS_AREA_M2,
    POMENIS_PATH,
    SOLAR_ARRAY_AREA_M2,
    pomenis_geometry,
    predict_pomenis,
    read_pomenis,
    starlink_model,
)


def test_observations_are_package_data():
    """Read through importlib.resources from the installed package, so a wheel carries them
    (`.ci/wheel-check` reads them from a wheel installed into a fresh environment)."""
    packaged = resources.files("lightcurve").joinpath(
        "data", "starlink", "pomenis_observations.csv"
    )
    assert packaged.is_file()
    assert POMENIS_PATH.samefile(str(packaged))
    assert len(read_pomenis()) == 1173


def test_model_surfaces():
    compiled = starlink_model().compiled()
    order = np.argsort(compiled.areas)
    np.testing.assert_allclose(compiled.areas[order], [CHASSIS_AREA_M2, SOLAR_ARRAY_AREA_M2])
    np.testing.assert_allclose(compiled.normals[order], [[0, 0, -1], [0, 1, 0]], atol=1e-12)


def test_geometry_and_attitude_law():
    table = read_pomenis()
    assert len(table) == 1173
    subset = table.iloc[::50]
    observations, q = pomenis_geometry(subset)
    axes = attitude_matrix(q)
    # Body y (row 1) is horizontal and points toward the Sun's side.
    sun = observations.sun_vectors / np.linalg.norm(observations.sun_vectors, axis=1)[:, None]
    assert np.all(np.einsum("ni,ni->n", axes[:, 1], sun) > 0)
    slant = np.linalg.norm(observations.observer_vectors, axis=1) / 1e3
    assert np.all((slant > 400) & (slant < 2000))


def test_prediction_without_fitting_tracks_the_measurements():
    """Regression guard on the figures reported in docs/validation.md (no fit to the data)."""
    result = predict_pomenis(read_pomenis().iloc[::5])
    assert np.all(np.isfinite(result.predicted))
    assert np.corrcoef(result.measured, result.predicted)[0, 1] > 0.5
    assert np.median(np.abs(result.residual)) < 1.5


def test_the_library_s_starlink_materials_are_the_lab_presets():
    """The built-in ``starlink_v1_5`` carries the two-lobe lab fits of the BRDF presets."""
    from brdf.materials import load_presets
    from shapes import get_library
    from shapes.material import STARLINK_CHASSIS, STARLINK_SOLAR_ARRAY

    presets = load_presets()
    library = get_library().load("starlink_v1_5")
    for group, constant, preset in (
        ("chassis", STARLINK_CHASSIS, "starlink-chassis"),
        ("solar_array", STARLINK_SOLAR_ARRAY, "starlink-solar-array"),
    ):
        assert constant.brdf == presets[preset].model
        assert constant.params == presets[preset].params
        assert library.materials[group].params == presets[preset].params
