"""The fewest faces the data need: a face the plain fit splits is merged back; a small face
the data see is kept; stabilised nights are left as fitted."""

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

import brdf
from lightcurve.analysis.egi import EGIFit, FitEpochs, design_matrix, fit_egi
from lightcurve.analysis.egi.simplify import choose_faces, fewest_faces
from lightcurve.photometry.render import flux_to_magnitude
from shapes import FacetModel

#: A 3 × 2 × 1 m box: its face normals (body frame) and areas (m²).
BOX_NORMALS = np.array(
    [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float
)
BOX_AREAS = np.array([2.0, 2.0, 3.0, 3.0, 6.0, 6.0])
MATERIAL = brdf.get("ashikhmin-shirley", rd=0.35, rs=0.25, nu=40, nv=40)
NOISE_MAG = 0.03
#: The normal of the bevel cut off the box's +x/+z edge.
BEVEL = np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)


def _tumbling_arc(normals: np.ndarray, areas: np.ndarray, seed: int) -> FitEpochs:
    """A 40-minute arc of 600 epochs of a body tumbling about two axes (0.3–1.5 °/s each),
    the phase angle sweeping only 20–24° (a geostationary arc's narrow band), noisy
    magnitudes (0.03 mag, seeded)."""
    count = 600
    rng = np.random.default_rng(seed)
    time_s = np.linspace(0.0, 2400.0, count)
    rates = np.radians(rng.uniform(0.3, 1.5, 2))
    attitude = Rotation.random(random_state=seed) * Rotation.from_euler(
        "zx", np.column_stack([rates[0] * time_s, rates[1] * time_s])
    )
    phase = np.radians(np.linspace(20.0, 24.0, count))
    light = attitude.inv().apply(np.tile([1.0, 0.0, 0.0], (count, 1)))
    view = attitude.inv().apply(np.column_stack([np.cos(phase), np.sin(phase), 0 * phase]))
    zeros = np.zeros(count)
    bare = FitEpochs(light, view, np.ones(count), zeros, zeros + 1, zeros.astype(int), zeros)
    flux = design_matrix(normals, bare, MATERIAL) @ areas
    mag = flux_to_magnitude(flux) + rng.normal(0.0, NOISE_MAG, count)
    return FitEpochs(
        light, view, np.ones(count), mag, np.full(count, NOISE_MAG), zeros.astype(int),
        time_s / 86400.0,
    )  # fmt: skip


def _bevelled_box(cut: float) -> tuple[np.ndarray, np.ndarray]:
    """Face normals and areas (m²) of the box with its +x/+z edge bevelled by ``cut`` m."""
    corners = np.array([[x, y, z] for x in (-1.5, 1.5) for y in (-1, 1) for z in (-0.5, 0.5)])
    edge = (corners[:, 0] > 0) & (corners[:, 2] > 0)
    points = np.vstack([corners[~edge], corners[edge] - [cut, 0, 0], corners[edge] - [0, 0, cut]])
    hull = trimesh.convex.convex_hull(points)
    compiled = FacetModel(hull.vertices, hull.faces).compiled()
    return compiled.normals, compiled.areas


def _nearest(fit: EGIFit, normal: np.ndarray) -> tuple[float, float]:
    """Angle (deg) from ``normal`` to the fit's nearest facet, and that facet's area."""
    angles = np.degrees(np.arccos(np.clip(fit.normals @ normal, -1.0, 1.0)))
    k = int(np.argmin(np.where(fit.areas > 0, angles, np.inf)))
    return float(angles[k]), float(fit.areas[k])


def test_a_face_the_plain_fit_splits_is_merged_back():
    """On a narrow band of phase angles the plain fit spreads the +z face over neighbouring
    facets; the fewest faces the data need are the box's six, within 2° of its normals."""
    epochs = _tumbling_arc(BOX_NORMALS, BOX_AREAS, seed=2)
    plain = fit_egi(epochs, MATERIAL, normals=500)
    near_top = (plain.normals @ [0.0, 0.0, 1.0] > np.cos(np.radians(15.0))) & (
        plain.areas >= 0.02 * plain.areas.sum()
    )
    assert near_top.sum() >= 2  # the split this step is for
    fewest = fewest_faces(plain, epochs)
    assert np.count_nonzero(fewest.areas) == 6
    for normal, area in zip(BOX_NORMALS, BOX_AREAS, strict=True):
        angle, found = _nearest(fewest, normal)
        assert angle < 2.0
        assert found == pytest.approx(area, rel=0.05)
    # it still fits the arc at the noise
    assert fewest.chi2 / len(epochs) < 1.1


def test_a_small_face_the_data_see_is_kept():
    """A bevel of 0.57 m² (2.6 % of the area) changes the arc's light curve by more than
    the information criterion's price: the simplified EGI keeps it."""
    normals, areas = _bevelled_box(0.2)
    bevel_area = float(areas[np.argmax(normals @ BEVEL)])
    epochs = _tumbling_arc(normals, areas, seed=2)
    fewest = fewest_faces(fit_egi(epochs, MATERIAL, normals=500), epochs)
    assert np.count_nonzero(fewest.areas) == 7
    angle, found = _nearest(fewest, BEVEL)
    assert angle < 3.0
    assert found == pytest.approx(bevel_area, rel=0.2)


def _unchanged_fit(count: int) -> EGIFit:
    return EGIFit(BOX_NORMALS, BOX_AREAS, 0 * BOX_AREAS, MATERIAL, np.ones(count), 1.0, 0.0)


def test_auto_leaves_a_stabilised_night_as_fitted_and_all_keeps_every_facet():
    """``auto`` simplifies only fits whose data see the normals from all sides: a night
    whose Sun–observer bisectors stay in one plane is kept as fitted (no refit runs)."""
    count = 60
    sweep = np.radians(np.linspace(20.0, 110.0, count))
    light = np.column_stack([np.cos(sweep), np.sin(sweep), np.zeros(count)])
    view = np.tile([1.0, 0.0, 0.0], (count, 1))
    zeros = np.zeros(count)
    night = FitEpochs(light, view, np.ones(count), zeros, zeros + 1, zeros.astype(int), zeros)
    fit = _unchanged_fit(count)
    assert choose_faces(fit, night, "auto") is fit
    assert choose_faces(fit, night, "all") is fit
    with pytest.raises(ValueError, match="faces must be one of auto, fewest, all"):
        choose_faces(fit, night, "some")
