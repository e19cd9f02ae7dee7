"""Rendering articulated shapes: per-part frames, joint shadowing, simulate columns."""

import math

import numpy as np
import pandas as pd
import pytest

from lightcurve.io.observations import Observations, validate_table
from lightcurve.photometry.articulated import ArticulatedRenderer
from lightcurve.photometry.render import Renderer
from lightcurve.photometry.simulate import simulate
from lightcurve.sky.geometry import AU_M
from shapes import FacetModel, Material, ShapeError, get_library, primitives
from shapes.articulation import ArticulatedModel, Articulation, axis_rotation

LAMBERT = Material("lambert", {"rd": 0.5})
DISTANCE = 4.0e7


def _cube_and_flap() -> ArticulatedModel:
    """A 1 m cube under a 2 × 2 m flap hinged along x at z = 1.5 m (flap angle from a column)."""
    cube = primitives.box((1.0, 1.0, 1.0))
    flap = primitives.plate(2.0, 2.0)
    vertices = np.vstack([cube.vertices, flap.vertices + np.array([0.0, 0.0, 1.5])])
    faces = np.vstack([cube.faces, flap.faces + len(cube.vertices)])
    index = np.concatenate([np.zeros(len(cube.faces)), flap.group_index + 1]).astype(int)
    model = FacetModel(
        vertices,
        faces,
        group_index=index,
        group_names=["body", "front", "back"],
        materials=LAMBERT,
        inertia="shell",
    )
    parts = [
        {
            "name": "flap",
            "groups": ["front", "back"],
            "joint": {
                "kind": "scheduled",
                "axis": [1, 0, 0],
                "pivot": [0, 0, 1.5],
                "column": "flap_deg",
                "limits_deg": [0, 90],
            },
        }
    ]
    return ArticulatedModel(model, Articulation.from_list(parts, model.group_names, "test"))


def _lambert_flux(area: float) -> float:
    """Flux ratio of a Lambert facet of ``area`` seen and lit face-on, Sun at 1 AU."""
    return 0.5 / math.pi * area / DISTANCE**2


@pytest.mark.parametrize("mode", ["exact", "table"])
def test_flap_shadows_the_cube_only_in_exact_mode(mode):
    shape = _cube_and_flap()
    renderer = ArticulatedRenderer(shape, shadows=mode)
    q = np.array([[0.0, 0.0, 0.0, 1.0]] * 2)
    sun = np.array([[0.0, 0.0, AU_M]] * 2)
    observer = np.array([[0.0, 0.0, DISTANCE]] * 2)
    flux = renderer.flux(q, sun, observer, {"flap_deg": np.array([0.0, 90.0])})
    # flap flat: its 4 m² front is lit; exact hides the cube top under it, table does not
    hidden = 0.0 if mode == "exact" else 1.0
    assert flux[0] == pytest.approx(_lambert_flux(4.0 + hidden), rel=1e-9)
    # flap edge-on to Sun and observer: the cube top alone
    assert flux[1] == pytest.approx(_lambert_flux(1.0), rel=1e-9)


def test_no_shadow_flux_equals_the_posed_rigid_shape_epoch_by_epoch():
    shape = get_library().load("box_wing_tracking", articulated=True, visibility=False)
    rng = np.random.default_rng(20261201)
    q = rng.normal(size=(6, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    sun = rng.normal(size=(6, 3)) * AU_M
    observer = rng.normal(size=(6, 3)) * DISTANCE
    renderer = ArticulatedRenderer(shape, shadows="none")
    flux = renderer.flux(q, sun, observer)
    angles = renderer.joint_angles(q, sun)[0]
    for e in range(6):
        rotation = axis_rotation(np.array([0.0, 1.0, 0.0]), np.radians(angles[e]))[None]
        posed = shape.posed(rotation)
        expected = Renderer(posed, shadows="none").flux(q[e], sun[e], observer[e])
        assert flux[e] == pytest.approx(float(expected), rel=1e-10)


def test_simulate_writes_joint_angles_and_reads_scheduled_columns():
    shape = _cube_and_flap()
    n = 5
    table = pd.DataFrame(
        {
            "mjd": 60379.0 + np.arange(n) / 1440.0,
            "sun_x": [0.0] * n,
            "sun_y": [0.3e8] * n,
            "sun_z": [1.496e8] * n,
            "obs_x": [1.0e4] * n,
            "obs_y": [0.0] * n,
            "obs_z": [4.0e4] * n,
            "flap_deg": np.linspace(0.0, 90.0, n),
        }
    )
    geometry = Observations(validate_table(table, "flap.csv", {}, require_magnitudes=False), {})
    result = simulate(
        geometry, shape, q0=[0, 0, 0, 1], omega0=[0, 0, 0], inertia=np.eye(3), shadows="exact"
    )
    assert np.allclose(result.table["joint_flap_deg"], np.linspace(0.0, 90.0, n))
    assert np.all(np.diff(result.table["mag"].to_numpy()) != 0.0)
    bad = geometry.table.assign(flap_deg=[0.0, 10.0, 120.0, 0.0, 0.0])
    with pytest.raises(ShapeError, match="column 'flap_deg', row 3"):
        simulate(Observations(bad, {}), shape, q0=[0, 0, 0, 1], omega0=[0, 0, 0], inertia=np.eye(3))
