"""Perturbed copies of library models: stretch, materials, mass, appendage, determinism."""

import json
import math

import numpy as np
import pytest

import brdf
from shapes import FacetModel, ShapeError, get_library, primitives
from shapes.material import BRDF_PARAMETERS, Material
from shapes.perturbation import (
    EXPONENTS,
    IMPLIED,
    KEPT,
    REFLECTANCES,
    ROUGHNESSES,
    UNIT_BOUNDED,
    WEIGHT_SUMS,
    perturbed_model,
)


@pytest.fixture(scope="module")
def library():
    return get_library()


def _draw(model, seed, **settings):
    return perturbed_model(model, np.random.default_rng(seed), **settings)


@pytest.mark.parametrize("name", ["box", "rocket_body", "box_wing"])
def test_stretch_scales_the_extents_along_the_principal_axes(library, name):
    model = library.load(name)
    for seed in range(3):
        drawn = _draw(model, seed, appendage=False)
        axes = drawn.stretch_axes
        np.testing.assert_allclose(axes, model.principal_axes)
        before = np.ptp(model.vertices @ axes, axis=0)
        after = np.ptp(drawn.model.vertices @ axes, axis=0)
        np.testing.assert_allclose(after / before, drawn.stretch, rtol=1e-9)
        assert np.all(np.abs(drawn.stretch - 1.0) <= 0.15)
        np.testing.assert_allclose(drawn.model.center_of_mass, model.center_of_mass, atol=1e-12)


def _all_brdfs_model() -> FacetModel:
    """A box whose six sides each carry one BRDF model, several at their bounds."""
    box = primitives.box((1.0, 1.5, 2.0))
    materials = {
        "lambert": Material("lambert", {"rd": 0.95}),
        "phong": Material("phong", {"rd": 0.5, "rs": 0.45, "n": 30.0}),
        "cook": Material("cook-torrance", {"rd": 0.3, "rs": 0.65, "m": 0.3, "f0": 0.9}),
        "aniso": Material(
            "ashikhmin-shirley",
            {"rd": 0.2, "rs": 0.5, "nu": 10.0, "nv": 100.0},
            reference_direction=(1.0, 1.0, 0.0),
        ),
        "regolith": Material("lommel-seeliger", {"c": 0.1, "a": 0.5, "d": 0.1, "k": -0.5}),
        "two_lobe": Material(
            "two-lobe",
            {"rd": 0.05, "rb": 0.2, "ab": 0.1, "fb": 1.0, "rn": 0.5, "mn": 0.002, "fn": 0.04},
        ),
    }
    sides = np.argmax(np.abs(box.normals), axis=1) * 2 + (box.normals.sum(axis=1) > 0)
    return FacetModel(
        box.vertices,
        box.faces,
        group_index=sides,
        group_names=list(materials),
        materials=materials,
        name="six_brdfs",
    )


def test_materials_stay_within_the_brdf_bounds_and_the_drawn_ranges():
    model = _all_brdfs_model()
    for seed in range(40):
        drawn = _draw(model, seed, appendage=False)
        for record in drawn.materials:
            brdf.get(record.brdf, **record.after)  # ranges and weight sums
            for key, factor in record.factors.items():
                if key in REFLECTANCES:
                    assert 0.7 - 1e-12 <= factor <= 1.3 + 1e-12
                elif key in EXPONENTS:
                    assert 0.5 - 1e-12 <= factor <= 2.0 + 1e-12
                else:
                    assert key in ROUGHNESSES
                    assert 2**-0.5 - 1e-12 <= factor <= 2**0.5 + 1e-12
            for key in set(record.before) & KEPT:
                assert record.after[key] == record.before[key]
        by_group = {r.group: r for r in drawn.materials}
        assert by_group["regolith"].after["w"] != 1.0  # the implied albedo is drawn too
        assert by_group["two_lobe"].after["fb"] <= 1.0
        assert by_group["aniso"].after["nu"] != by_group["aniso"].after["nv"]


def test_an_isotropic_lobe_stays_isotropic(library):
    model = library.load("box")  # MLI, nu = nv
    for seed in range(5):
        (record,) = _draw(model, seed, appendage=False).materials
        assert record.after["nu"] == record.after["nv"]
        assert record.factors["nu"] != 1.0


def test_rule_tables_agree_with_the_brdf_registry():
    for name, (required, optional) in BRDF_PARAMETERS.items():
        info = brdf.describe(name)
        for key in required + optional:
            assert key in REFLECTANCES | EXPONENTS | ROUGHNESSES | KEPT, (name, key)
            spec = info.parameter(key)
            assert (key in UNIT_BOUNDED and key in info.weights) or key not in info.weights
            if key in UNIT_BOUNDED:
                assert spec.upper == 1.0
            if key in EXPONENTS | ROUGHNESSES:
                assert spec.log_scale
        assert WEIGHT_SUMS.get(name, ()) == info.weights
        for key, value in IMPLIED.get(name, {}).items():
            assert key in optional and info.parameter(key).default == value


def test_moments_are_five_to_ten_percent_off_and_the_axes_tilted_at_most_five_degrees(library):
    model = library.load("box")
    for seed in range(10):
        drawn = _draw(model, seed, appendage=False)
        stretched = FacetModel(
            drawn.model.vertices, drawn.model.faces, inertia="solid", mass=model.mass
        )
        nominal = np.diag(drawn.stretch_axes.T @ stretched.inertia @ drawn.stretch_axes)
        np.testing.assert_allclose(drawn.nominal_moments, nominal, rtol=1e-9)
        moments, vectors = np.linalg.eigh(drawn.model.inertia)
        # The box's moments are well apart: match each true axis to its geometric one.
        match = np.argmax(np.abs(drawn.stretch_axes.T @ vectors), axis=0)
        assert sorted(match) == [0, 1, 2]
        offsets = moments / nominal[match] - 1.0
        assert np.all((np.abs(offsets) >= 0.05 - 1e-9) & (np.abs(offsets) <= 0.10 + 1e-9))
        cosines = np.abs(np.sum(drawn.stretch_axes[:, match] * vectors, axis=0))
        angles = np.degrees(np.arccos(np.clip(cosines, -1.0, 1.0)))
        assert np.all(angles <= drawn.tilt_deg + 1e-6)
        assert drawn.tilt_deg <= 5.0
        np.testing.assert_allclose(drawn.model.inertia, drawn.inertia)
        assert drawn.model.inertia_source == "given"


def test_a_flat_plate_gets_physical_moments_and_no_appendage(library):
    model = library.load("plate")  # shell: J3 = J1 + J2
    for seed in range(5):
        drawn = _draw(model, seed)
        ordered = np.sort(drawn.moments)
        assert ordered[2] <= ordered[0] + ordered[1]
        assert drawn.appendage is None and drawn.appendage_note
        assert len(drawn.model.faces) == len(model.faces)


def test_the_same_seed_gives_the_same_model(library):
    model = library.load("box_wing")
    first, again, other = _draw(model, 7), _draw(model, 7), _draw(model, 8)
    assert first.model.fingerprint == again.model.fingerprint
    np.testing.assert_array_equal(first.model.inertia, again.model.inertia)
    assert first.to_dict() == again.to_dict()
    assert other.model.fingerprint != first.model.fingerprint


@pytest.mark.parametrize("kind", ["antenna", "thruster"])
def test_an_appendage_adds_facets_outside_the_body(library, kind):
    model = library.load("box")
    for seed in range(5):
        drawn = _draw(model, seed, appendage=kind)
        plain = _draw(model, seed, appendage=False)
        part = drawn.appendage
        assert part is not None and part.kind == kind and part.host_group == "body"
        assert len(drawn.model.faces) == len(model.faces) + part.facets
        assert drawn.model.group_names == ["body", kind]
        np.testing.assert_array_equal(drawn.stretch, plain.stretch)
        np.testing.assert_array_equal(drawn.model.inertia, plain.model.inertia)
        # In the stretch frame the body is |x_k| ≤ half extent; the part stands outside it.
        half = 0.5 * np.ptp(plain.model.vertices @ drawn.stretch_axes, axis=0)
        added = drawn.model.vertices[len(plain.model.vertices) :] @ drawn.stretch_axes
        assert np.all(np.any(np.abs(added) >= half - 1e-9, axis=1))
        base = part.base @ drawn.stretch_axes
        assert np.isclose(np.max(np.abs(base) / half), 1.0)  # on a face
        assert drawn.model.is_watertight and not drawn.model.is_convex


def test_the_appendage_keeps_clear_of_the_other_parts(library):
    model = library.load("box_wing")
    for seed in range(6):
        drawn = _draw(model, seed, appendage="antenna")
        part = drawn.appendage
        assert part is not None and part.host_group == "bus"  # not on a solar-array sheet
        # Nothing of the model lies in front of the footprint's centre along the axis.
        rel = drawn.model.vertices[:-8] - part.base
        along = rel @ part.direction
        across = np.linalg.norm(rel - np.outer(along, part.direction), axis=1)
        assert not np.any((along > 1e-9) & (across < 0.5 * part.size["width"]))


def test_the_perturbed_model_renders_finite_fluxes(library):
    from filters.attitude import random_quaternion
    from lightcurve.photometry.render import Renderer

    drawn = _draw(library.load("box_wing"), 3, appendage="thruster")
    assert drawn.appendage is not None
    rng = np.random.default_rng(0)
    q = random_quaternion((64,), rng)
    sun = np.tile([1.5e8, 2.0e7, 0.0], (64, 1))
    observer = np.tile([3.0e4, 2.0e4, 1.0e4], (64, 1))
    flux = np.asarray(Renderer(drawn.model, shadows="exact").flux(q, sun, observer))
    assert np.all(np.isfinite(flux)) and np.all(flux >= 0) and np.any(flux > 0)


def test_the_record_is_json_ready(library):
    drawn = _draw(library.load("rocket_body"), 2)
    record = json.loads(json.dumps(drawn.to_dict()))
    assert record["parent"] == "rocket_body"
    assert len(record["stretch"]) == 3 and len(record["materials"]) == 3
    assert math.isclose(max(record["moment_ratios"]), 1.0)
    assert drawn.model.provenance["perturbed_from"] == "rocket_body"


@pytest.mark.parametrize(
    "settings",
    [
        {"stretch": 1.0},
        {"albedo": -0.1},
        {"exponent_factor": 0.5},
        {"moment_range": (0.1, 0.05)},
        {"tilt_deg": -1.0},
        {"appendage": "solar_sail"},
    ],
)
def test_bad_settings_are_refused(library, settings):
    with pytest.raises(ShapeError):
        _draw(library.load("box"), 0, **settings)
