"""The smoothness weight the geometry needs: stabilised nights get one, tumbling arcs none."""

import numpy as np
import pytest

import brdf
from filters.attitude import attitude_matrix, random_quaternion
from lightcurve.analysis.egi import FitEpochs, design_matrix, fit_egi
from lightcurve.analysis.egi.fit import default_smoothing
from lightcurve.photometry.render import flux_to_magnitude

#: A 3 × 2 × 1 m box: its face normals (body frame) and areas (m²).
BOX_NORMALS = np.array(
    [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float
)
BOX_AREAS = np.array([2.0, 2.0, 3.0, 3.0, 6.0, 6.0])
MATERIAL = brdf.get("ashikhmin-shirley", rd=0.35, rs=0.25, nu=40, nv=40)
NOISE_MAG = 0.03


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _epochs(light: np.ndarray, view: np.ndarray, turn: np.ndarray, seed: int) -> FitEpochs:
    """Noisy magnitudes of the box turned by ``turn`` (body frame) at these directions."""
    flux = design_matrix(BOX_NORMALS @ turn.T, _bare(light, view), MATERIAL) @ BOX_AREAS
    mag = flux_to_magnitude(flux) + np.random.default_rng(seed).normal(0, NOISE_MAG, len(flux))
    return FitEpochs(
        light, view, np.ones(len(flux)), mag, np.full(len(flux), NOISE_MAG),
        np.zeros(len(flux), int), np.arange(len(flux)) / 1440.0,
    )  # fmt: skip


def _bare(light: np.ndarray, view: np.ndarray) -> FitEpochs:
    n = len(light)
    zeros = np.zeros(n)
    return FitEpochs(light, view, np.ones(n), zeros, zeros + 1, zeros.astype(int), zeros)


def _stabilised_night(declination_deg: float, seed: int) -> FitEpochs:
    """A stabilised object's night: the observer fixed in the body frame, the Sun sweeping
    90° of a cone about the body z axis (the orbit normal of a nadir-pointing object)."""
    sweep = np.radians(np.linspace(20.0, 110.0, 240))
    dec = np.radians(declination_deg)
    light = np.column_stack(
        [np.cos(dec) * np.cos(sweep), np.cos(dec) * np.sin(sweep), np.full(240, np.sin(dec))]
    )
    view = np.tile(_unit(np.array([0.9, 0.3, 0.2])), (240, 1))
    turn = attitude_matrix(random_quaternion((), np.random.default_rng(7)))
    return _epochs(light, view, turn, seed)


def _held_out_rms(fit, held_out: FitEpochs) -> float:
    model = flux_to_magnitude(design_matrix(fit.normals, held_out, MATERIAL) @ fit.areas)
    return float(np.sqrt(np.mean((held_out.mag - model) ** 2)))


def test_a_stabilised_night_gets_a_weight_that_keeps_its_areas_and_predicts_another_night():
    """Non-negativity and closure alone let a night seen along one band of normals put
    area of any size where it hardly sees; the weight keeps the box's size."""
    night = _stabilised_night(-20.0, 1)
    other = _stabilised_night(-12.0, 2)  # another night: the Sun's declination 8° away
    weight = default_smoothing(night)
    assert weight > 0.0
    plain = fit_egi(night, MATERIAL, normals=500, smoothing=0.0)
    smooth = fit_egi(night, MATERIAL, normals=500, smoothing=weight)
    assert _held_out_rms(smooth, night) < 1.2 * NOISE_MAG  # both fit the night itself
    assert _held_out_rms(plain, night) < 1.2 * NOISE_MAG
    assert 0.5 < smooth.areas.sum() / BOX_AREAS.sum() < 2.0
    assert _held_out_rms(smooth, other) < 0.5 * _held_out_rms(plain, other)


def test_a_tumbling_arc_gets_no_weight_and_its_fit_predicts_another_arc():
    rng = np.random.default_rng(3)
    light = _unit(rng.standard_normal((300, 3)))
    view = _unit(light + 0.1 * rng.standard_normal((300, 3)))  # phase angles of a few degrees
    arc = _epochs(light, view, np.eye(3), 4)
    assert default_smoothing(arc) == 0.0
    fit = fit_egi(arc, MATERIAL, normals=500)
    light = _unit(rng.standard_normal((200, 3)))  # another arc, at phase angles of 10–30°
    view = _unit(light + rng.uniform(0.2, 0.5, (200, 1)) * _unit(rng.standard_normal((200, 3))))
    other = _epochs(light, view, np.eye(3), 5)
    assert _held_out_rms(fit, arc) < 1.2 * NOISE_MAG
    assert _held_out_rms(fit, other) < 1.5 * NOISE_MAG


@pytest.mark.parametrize("weight", [-1.0, np.nan, np.inf])
def test_a_bad_weight_is_an_error(weight):
    night = _stabilised_night(-20.0, 1)
    with pytest.raises(ValueError, match="smoothing must be finite"):
        fit_egi(night, MATERIAL, normals=100, smoothing=weight)


@pytest.mark.parametrize("text", ["-1", "nan", "inf", "much"])
def test_the_command_rejects_a_bad_weight(text):
    import argparse

    from lightcurve.commands.shape import _smoothing

    assert _smoothing("auto") == "auto" and _smoothing("1e-3") == 1e-3
    with pytest.raises(argparse.ArgumentTypeError, match="'auto' or a finite number"):
        _smoothing(text)
