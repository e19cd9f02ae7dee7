"""The EGI of light curves with known attitudes: design matrix, fit, reconstruction, epochs."""

import json

import numpy as np
import pandas as pd
import pytest

import brdf
from lightcurve import io
from lightcurve.analysis.egi import (
    FitEpochs,
    convex_solid,
    design_matrix,
    fit_egi,
    fit_material,
    normal_grid,
    smoothness_operator,
)
from lightcurve.analysis.egi.epochs import result_attitudes, truth_attitudes
from lightcurve.analysis.egi.fit import cluster_normals
from lightcurve.io.observations import Observations
from lightcurve.photometry.render import Renderer
from shapes import material, primitives

from .._egi import known_attitude_file
from .._geometry import random_geometry

BOX_SIZE = (3.0, 2.0, 1.0)
BOX_NORMALS = np.array(
    [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float
)
BOX_AREAS = np.array([2.0, 2.0, 3.0, 3.0, 6.0, 6.0])


def _box(model: material.Material):
    return primitives.box(BOX_SIZE, materials={"body": model})


@pytest.fixture(scope="module")
def lambert_box_epochs(tmp_path_factory):
    path = tmp_path_factory.mktemp("egi") / "box.csv"
    known_attitude_file(_box(material.Material("lambert", {"rd": 0.3})), path, epochs=400, seed=3)
    obs = io.read(path)
    return FitEpochs.from_observations([obs], [truth_attitudes(obs)])


def test_grid_is_unit_and_near_uniform():
    grid = normal_grid(2000)
    assert np.allclose(np.linalg.norm(grid, axis=1), 1.0)
    assert np.linalg.norm(grid.mean(axis=0)) < 1e-3
    # Every direction has a grid normal within the lattice's spacing √(4π/N).
    probe = normal_grid(137)
    nearest = np.degrees(np.arccos(np.max(probe @ grid.T, axis=1)))
    assert nearest.max() < np.degrees(np.sqrt(4 * np.pi / 2000))
    operator = smoothness_operator(grid[:50])
    assert np.allclose(operator @ np.ones(50), 0.0)


@pytest.mark.parametrize(
    "model",
    [
        material.Material("lambert", {"rd": 0.3}),
        material.Material("ashikhmin-shirley", {"rd": 0.3, "rs": 0.2, "nu": 30, "nv": 30}),
    ],
)
def test_design_matrix_times_box_egi_is_the_renderer_flux(model):
    """Independent check: the EGI design against the project's renderer on the box mesh."""
    q, sun, obs = random_geometry(200, 5)
    sun *= np.linspace(0.98, 1.02, 200)[:, None]  # the renderer scales by (1 AU / r_sun)²
    obs_file = Observations(
        pd.DataFrame(
            {
                "mjd": 60000.0 + np.arange(200) / 86400.0,
                "mag": 10.0,
                "mag_err": 0.01,
                **{f"sun_{a}": sun[:, i] / 1e3 for i, a in enumerate("xyz")},
                **{f"obs_{a}": obs[:, i] / 1e3 for i, a in enumerate("xyz")},
            }
        )
    )
    epochs = FitEpochs.from_observations([obs_file], [q])
    params = dict(model.params)
    flux = design_matrix(BOX_NORMALS, epochs, brdf.get(model.brdf, **params)) @ BOX_AREAS
    rendered = Renderer(_box(model), shadows="none").flux(q, sun, obs)
    assert np.allclose(flux, rendered, rtol=1e-9, atol=1e-30)


def test_lambert_box_areas_and_normals_recovered(lambert_box_epochs):
    fit = fit_egi(lambert_box_epochs, brdf.get("lambert", rd=0.3), normals=1000)
    assert fit.residual_rms_mag(lambert_box_epochs) < 1.2 * 0.02
    merged, areas = cluster_normals(fit.normals, fit.areas, 0.1)
    for normal, area in zip(BOX_NORMALS, BOX_AREAS, strict=True):
        near = merged @ normal > np.cos(np.radians(5.0))
        assert abs(areas[near].sum() / area - 1) < 0.05
        mean = areas[near] @ merged[near]
        assert np.degrees(np.arccos(mean @ normal / np.linalg.norm(mean))) < 1.0
    assert abs(fit.areas.sum() / BOX_AREAS.sum() - 1) < 0.05
    assert np.all(fit.area_sigma[fit.areas > 0] > 0)


def test_fewer_epochs_than_the_normals_support_is_an_error(lambert_box_epochs):
    few = lambert_box_epochs.subset(np.arange(len(lambert_box_epochs)) < 20)
    with pytest.raises(ValueError, match="20 epochs cannot support an EGI of 1000 normals"):
        fit_egi(few, brdf.get("lambert"), normals=1000)


def test_material_search_finds_lambert_in_the_phong_family(lambert_box_epochs):
    few = lambert_box_epochs.subset(np.arange(len(lambert_box_epochs)) < 200)
    fit = fit_material(few, ("phong",), normals=300, albedo=0.3)
    assert fit.material.name == "phong"
    assert fit.material.params["rs"] < 0.02
    # rd assumed at the truth's 0.3: the total area is the box's.
    assert abs(fit.areas.sum() / BOX_AREAS.sum() - 1) < 0.1


def test_reconstruction_of_a_known_egi_is_the_polyhedron():
    solid = convex_solid(BOX_NORMALS, BOX_AREAS)
    assert solid.n_facets == 6
    assert np.allclose(solid.axis_ratios, [1.5, 2.0], rtol=1e-6)
    assert solid.model.volume == pytest.approx(6.0, rel=1e-6)
    extent = np.ptp(solid.model.vertices, axis=0)
    assert np.allclose(np.sort(extent), [1.0, 2.0, 3.0], rtol=1e-6)


def test_reconstruction_of_a_prism_egi():
    """Right triangular prism: equilateral base of side 2, height 3 (areas in closed form)."""
    side, height = 2.0, 3.0
    angles = np.radians([90.0, 210.0, 330.0])
    sides = np.column_stack([np.cos(angles), np.sin(angles), np.zeros(3)])
    normals = np.vstack([sides, [[0, 0, 1.0], [0, 0, -1.0]]])
    base = np.sqrt(3) / 4 * side**2
    areas = np.array([side * height] * 3 + [base, base])
    solid = convex_solid(normals, areas)
    assert solid.n_facets == 5
    assert solid.model.volume == pytest.approx(base * height, rel=1e-6)
    # Principal frame: the prism's axis (a principal axis) is one of x, y, z; its length is 3.
    extent = np.sort(np.ptp(solid.model.vertices, axis=0))
    assert extent[-1] == pytest.approx(height, rel=1e-6)
    assert extent[0] == pytest.approx(np.sqrt(3), rel=1e-6)  # the triangle's height


def _result_folder(folder, source, mjd, q):
    folder.mkdir(parents=True)
    (folder / "summary.json").write_text(json.dumps({"input": str(source), "status": "ok"}))
    table = pd.DataFrame({"mjd": mjd, **{f"q{i + 1}": q[:, i] for i in range(4)}})
    table.to_parquet(folder / "estimates.parquet")


def test_result_attitudes_are_matched_by_epoch_and_file(tmp_path):
    path = known_attitude_file(
        _box(material.Material("lambert", {"rd": 0.3})), tmp_path / "obj.csv", epochs=60, seed=4
    )
    obs = io.read(path)
    truth = truth_attitudes(obs)
    _result_folder(tmp_path / "batch" / "obj", path, obs.mjd, truth)
    assert np.array_equal(result_attitudes(obs, tmp_path / "batch"), truth)  # batch folder
    assert np.array_equal(result_attitudes(obs, tmp_path / "batch" / "obj"), truth)
    other = tmp_path / "other"
    _result_folder(other, tmp_path / "else.csv", obs.mjd, truth)
    with pytest.raises(ValueError, match="the result of another file"):
        result_attitudes(obs, other)
    shifted = tmp_path / "shifted"
    _result_folder(shifted, path, obs.mjd + 1.0, truth)
    with pytest.raises(ValueError, match="no estimate at 60 of the 60 epochs"):
        result_attitudes(obs, shifted)
