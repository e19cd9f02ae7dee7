"""The adjusted shape against the renderer on meshes that really are stretched, and its
dynamics against the mass properties of those meshes."""

from __future__ import annotations

import numpy as np
import pytest

from filters.attitude import PrincipalInertia, inertia_ratios
from lightcurve.photometry.adjusted import ADJUSTMENTS, AdjustableShape
from lightcurve.photometry.render import Renderer
from lightcurve.sky.geometry import AU_M
from shapes import get_library


def _directions(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _renderer_flux(shape, light: np.ndarray, view: np.ndarray, shadows: str) -> np.ndarray:
    """Flux ratio at unit distances (Sun at 1 AU, observer at 1 m), identity attitude."""
    q = np.tile([0.0, 0.0, 0.0, 1.0], (len(light), 1))
    return Renderer(shape, shadows=shadows).flux(q, light * AU_M, view)


def _stretched(shape, adjustable: AdjustableShape, theta: np.ndarray):
    """The library mesh with its vertices really stretched about the centre of mass."""
    d = adjustable.stretch_matrix(theta)
    com = shape.center_of_mass
    return shape.replace(vertices=(shape.vertices - com) @ d + com).with_visibility(None)


@pytest.mark.parametrize("name", ["box", "rocket_body", "box_wing"])
def test_library_model_at_zero(name: str) -> None:
    shape = get_library().load(name)
    adjustable = AdjustableShape(shape, ADJUSTMENTS)
    rng = np.random.default_rng(1)
    light, view = _directions(rng, 40), _directions(rng, 40)
    expected = _renderer_flux(shape, light, view, adjustable.shadows)
    got = adjustable.flux(adjustable.initial, light, view)
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12 * expected.max())


@pytest.mark.parametrize("name", ["box", "rocket_body"])
def test_stretch_matches_a_stretched_mesh(name: str) -> None:
    shape = get_library().load(name)
    adjustable = AdjustableShape(shape, ("stretch",))
    theta = np.log([1.12, 0.86, 1.07])  # inside the bound: u ≈ ln s
    rng = np.random.default_rng(2)
    light, view = _directions(rng, 60), _directions(rng, 60)
    expected = _renderer_flux(_stretched(shape, adjustable, theta), light, view, "none")
    np.testing.assert_allclose(adjustable.flux(theta, light, view), expected, rtol=1e-9)


def test_stretch_of_a_shadowed_shape_follows_ray_casting() -> None:
    """Shadows at the mapped directions ``D⁻¹L`` against ray casting on the stretched mesh."""
    shape = get_library().load("box_wing").with_visibility(None)
    adjustable = AdjustableShape(shape, ("stretch",))
    assert adjustable.shadows == "exact"
    theta = np.log([1.1, 0.9, 1.05])
    rng = np.random.default_rng(3)
    light, view = _directions(rng, 30), _directions(rng, 30)
    expected = _renderer_flux(_stretched(shape, adjustable, theta), light, view, "exact")
    got = adjustable.flux(theta, light, view)
    # both ray-cast on sample points; the points of the stretched mesh are not the images
    # of the library mesh's, so the fractions agree to the sampling, not to rounding
    assert np.max(np.abs(got - expected)) < 0.02 * expected.max()


def test_stretched_inertia_is_the_stretched_mesh_inertia() -> None:
    shape = get_library().load("box")
    adjustable = AdjustableShape(shape, ("stretch",))
    theta = np.log([1.15, 0.9, 1.05])
    got = adjustable.principal_inertia(theta[None])
    truth = PrincipalInertia.from_inertia(_stretched(shape, adjustable, theta).inertia)
    np.testing.assert_allclose(got.ratios[0], truth.ratios, atol=1e-9)


def test_scale_material_tilt_and_inertia() -> None:
    shape = get_library().load("box")
    adjustable = AdjustableShape(shape, ("inertia", "tilt", "scale", "material"))
    names = adjustable.names
    theta = adjustable.initial.copy()
    theta[names.index("magnitude_offset")] = 0.5
    rng = np.random.default_rng(4)
    light, view = _directions(rng, 20), _directions(rng, 20)
    base = adjustable.flux(adjustable.initial, light, view)
    np.testing.assert_allclose(adjustable.flux(theta, light, view), base * 10**-0.2)
    # a material parameter moves by its factor and stays within its physical range
    rd = names.index("MLI.rd")
    theta[rd] = np.log(10.0)
    values = adjustable.physical(theta)
    assert values["MLI.rd"] + values["MLI.rs"] <= 1.0 + 1e-12
    # the tanh inertia parameters give the ratios; a tilt turns the principal axes
    k = adjustable.initial[[names.index("k1"), names.index("k2")]]
    theta[names.index("tilt_z")] = np.radians(4.0)
    inertia = adjustable.principal_inertia(theta[None])
    np.testing.assert_allclose(
        inertia.ratios[0], inertia_ratios(np.sort(np.diag(shape.inertia))), atol=1e-12
    )
    assert k.shape == (2,)
    turned = np.degrees(
        np.arccos(np.clip(np.sum(inertia.axes[0] * shape.principal_axes, 0), -1, 1))
    )
    assert np.isclose(np.max(turned), 4.0, atol=1e-6)
    assert values["tilt_deg"] == pytest.approx(0.0)


def test_describe_propagates_sigma() -> None:
    adjustable = AdjustableShape(get_library().load("box"), ("stretch", "scale"))
    covariance = np.diag(np.full(len(adjustable), 0.01**2))
    described = adjustable.describe(adjustable.initial, covariance)
    assert described["stretch_1"]["value"] == pytest.approx(1.0)
    assert described["stretch_1"]["sigma"] == pytest.approx(0.01, rel=1e-6)
    assert described["magnitude_offset"]["sigma"] == pytest.approx(0.01, rel=1e-6)


def test_unknown_adjustment() -> None:
    with pytest.raises(ValueError, match="unknown adjustment"):
        AdjustableShape(get_library().load("box"), ("stretch", "colour"))


def test_an_isotropic_lobe_stays_isotropic() -> None:
    shape = get_library().load("box")
    adjustable = AdjustableShape(shape, ("material",))
    names = adjustable.names
    assert "MLI.nu=nv" in names
    assert not {"MLI.nu", "MLI.nv"} & set(names)
    theta = adjustable.initial.copy()
    theta[names.index("MLI.nu=nv")] = np.log(1.7)
    (model,) = adjustable.materials(theta)
    (library,) = adjustable.materials(adjustable.initial)
    assert model.params["nu"] == model.params["nv"]
    assert model.params["nu"] == pytest.approx(1.7 * library.params["nu"])
    assert adjustable.physical(theta)["MLI.nu=nv"] == pytest.approx(model.params["nu"])


def test_a_flat_body_keeps_its_inertia() -> None:
    """J3 = J1 + J2 (a plate): the fit starts at the plate's inertia ratios, not a disc's."""
    plate = get_library().load("plate")
    adjustable = AdjustableShape(plate, ("inertia", "scale"))
    assert adjustable.estimate == ("inertia", "scale")
    ratios = adjustable.principal_inertia(adjustable.initial[None]).ratios[0]
    np.testing.assert_allclose(ratios, inertia_ratios(plate.principal_moments), atol=1e-5)
