"""The joint mode's attitude step: the inversion's first state in the principal frame."""

import numpy as np

from benchmarks import shape_recovery
from lightcurve.analysis.egi.search import torque_free_attitudes
from lightcurve.io.observations import Observations
from lightcurve.joint_shape import inverted_states
from lightcurve.photometry.render import Renderer
from shapes import FacetModel


def test_the_inverted_state_reproduces_the_light_curve_in_the_principal_frame():
    # A light curve admits several attitude histories (the inversion reports six states
    # within Δχ² < 9 here): the check is the fit, not the attitude.
    shape = shape_recovery.objects()["box_3x2x1"]
    arc = shape_recovery.observe(shape, "geo_tumbling", np.random.default_rng(11), 0.02)
    arc = Observations(arc.table.iloc[:300].reset_index(drop=True), arc.meta, arc.source)
    [(first, omega)], ratios, rms, [estimated] = inverted_states([arc], shape, 0)
    moments, axes = np.linalg.eigh(shape.inertia)
    assert np.allclose(ratios, moments[1:] / moments[0])
    assert rms < 0.03
    axes = axes * np.sign(np.linalg.det(axes))
    principal = FacetModel(shape.vertices @ axes, shape.faces, materials=shape_recovery.MATERIAL)
    head = np.arange(100)
    seconds = (arc.mjd[head] - arc.mjd[0]) * 86400.0
    q = torque_free_attitudes(first, omega, ratios, seconds)
    mag = Renderer(principal, shadows="none").magnitude(
        q, arc.sun_vectors[head], arc.observer_vectors[head]
    )
    assert np.sqrt(np.mean((mag - arc.magnitudes[head]) ** 2)) < 0.03
    assert np.allclose(np.abs(np.sum(estimated[0] * first)), 1.0)
