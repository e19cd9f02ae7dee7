"""The light-curve error of a proxy: zero against itself, falling as the proxy gets finer,
the geometries within the phase limit, and a proxy shadowed otherwise than its shape refused."""

from __future__ import annotations

import numpy as np
import pytest

from lightcurve.photometry.proxy_error import MAX_PHASE_DEG, ProxyErrorMeter, random_geometries
from shapes import primitives
from shapes.library.proxy import decimate


def test_geometries_are_seeded_and_within_the_phase_limit():
    q, sun, observer = random_geometries(500, 7)
    cos_phase = np.einsum("ij,ij->i", sun, observer) / (
        np.linalg.norm(sun, axis=1) * np.linalg.norm(observer, axis=1)
    )
    assert np.all(cos_phase >= np.cos(np.radians(MAX_PHASE_DEG)) - 1e-12)
    assert cos_phase.min() < np.cos(np.radians(MAX_PHASE_DEG - 10))  # the range is covered
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0)
    np.testing.assert_array_equal(random_geometries(500, 7)[1], sun)


def test_error_falls_as_the_proxy_gets_finer():
    sphere = primitives.icosphere(1.0, subdivisions=3)  # convex: rendered without shadows
    meter = ProxyErrorMeter(geometries=1000, seed=3)
    assert meter(sphere, sphere)["rms_mag"] == 0.0
    coarse = meter(sphere, decimate(sphere, 80))
    fine = meter(sphere, decimate(sphere, 320))
    assert coarse["shadows"] == fine["shadows"] == "none"
    # the regolith's phase function (DAMIT defaults) is negative beyond 114.6°: dark there
    assert 900 < coarse["geometries"] < 1000 and coarse["seed"] == 3
    assert 0.0 < fine["rms_mag"] < coarse["rms_mag"] <= coarse["max_mag"]
    # a sphere's magnitude depends on the phase angle only: an inscribed polyhedron of 320
    # facets is within a few hundredths of a magnitude of the 1280-facet one
    assert fine["rms_mag"] < 0.03


def test_a_proxy_shadowed_otherwise_is_refused():
    sphere = primitives.icosphere(1.0, subdivisions=3)
    dented = primitives.box_wing()  # non-convex without a table: ray-cast
    with pytest.raises(ValueError, match="renders with shadows 'exact'"):
        ProxyErrorMeter(geometries=10)(sphere, dented)
    with pytest.raises(ValueError, match="at least 10 geometries"):
        ProxyErrorMeter(geometries=5)


def test_a_progress_bar_leaves_the_record_unchanged(capsys):
    """With ``progress`` each model's render draws a bar on stderr; the record is the same."""
    sphere = primitives.icosphere(1.0, subdivisions=3)
    proxy = decimate(sphere, 80)
    quiet = ProxyErrorMeter(geometries=2500, seed=4)(sphere, proxy)
    shown = ProxyErrorMeter(geometries=2500, seed=4, progress=True)(sphere, proxy)
    assert shown["rms_mag"] == pytest.approx(quiet["rms_mag"], rel=1e-12)
    assert shown["geometries"] == quiet["geometries"]
    error = capsys.readouterr().err
    assert "1280 facets" in error and "proxy, 80 facets" in error and "2500/2500" in error
