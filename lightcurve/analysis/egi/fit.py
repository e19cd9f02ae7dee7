"""The EGI fit: the design matrix, the non-negative least squares, the material search and
the areas' 1σ.

For facets of area ``a_n`` over fixed unit normals ``n`` (body frame), the flux ratio at
epoch ``e`` is linear in the areas (docs/rendering.md, "The measurement model"; convex body,
no shadows):

``F_e = Σ_n A[e, n] a_n``,  ``A[e, n] = ρ(n, L_e, V_e) max(0, n·L_e) max(0, n·V_e) / d_e²``.

The areas minimise ``Σ_e ((F_e − F_obs,e)/σ_e)² + λ ‖K a‖²`` over ``a ≥ 0`` with
``σ_e = 0.4 ln 10 · F_obs,e · σ_mag,e`` (the magnitude errors carried to flux) and ``K`` the
neighbour Laplacian of :func:`~lightcurve.analysis.egi.grid.smoothness_operator`: a
Tikhonov term towards an EGI that varies slowly over the sphere (Tikhonov & Arsenin 1977),
its weight ``λ = smoothing · tr(AᵀWA) / tr(KᵀK)`` relative to the data's. The problem is
solved by the active-set method of Lawson & Hanson (1974, *Solving Least Squares Problems*,
ch. 23; :func:`scipy.optimize.nnls`).

With the material unknown, :func:`fit_material` fits one specular weight ``rs`` and the
lobe's exponent of a registry model (Ashikhmin–Shirley by default) with the diffuse albedo
``rd`` held at an assumed value: the flux fixes only the product of reflectance and area.

A closed surface has ``Σ_n a_n n = 0`` (Minkowski 1897); three rows of weight
:data:`CLOSURE_WEIGHT` hold the fit to it, which keeps areas off normals the data hardly see.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import least_squares, minimize_scalar, nnls
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

import brdf
from lightcurve.analysis.egi.epochs import FitEpochs
from lightcurve.analysis.egi.grid import normal_grid, smoothness_operator
from lightcurve.photometry.render import flux_to_magnitude

__all__ = [
    "EGIFit",
    "bootstrap_areas",
    "check_epochs",
    "default_smoothing",
    "design_matrix",
    "egi_residuals",
    "fit_egi",
    "fit_material",
    "fit_result",
    "min_epochs",
    "solve_areas",
]

#: Fewest epochs of any fit, and epochs per normal: below these the data cannot hold the
#: grid's areas (and the smoothing, not the data, would make the shape).
MIN_EPOCHS = 30
NORMALS_PER_EPOCH = 20
#: Normals of the grid on which :func:`fit_material` compares materials.
MATERIAL_SEARCH_NORMALS = 500
#: Rounds of cluster normals added to the grid (:func:`fit_egi`).
REFINEMENTS = 3
#: Smallest share of the total area of a facet refined off the grid (:func:`polish`).
POLISH_SHARE = 0.02
#: Residual evaluations of one polish at most (besides the finite-difference Jacobians).
POLISH_STEPS = 20
#: Weight of the closure rows relative to the mean squared column of the data.
CLOSURE_WEIGHT = 1e4
#: Smallest eigenvalue of the body-frame bisectors' scatter below which the data see the
#: normals along one band only (:func:`default_smoothing`): bisectors within about ±6° of
#: a plane.
BAND_SPREAD = 0.01
#: Relative smoothness weight of a fit whose data see one band of normals.
BAND_SMOOTHING = 1e-4


def min_epochs(normals: int) -> int:
    """Fewest epochs an EGI of ``normals`` normals is fitted to: ``max(30, N/20)``."""
    return max(MIN_EPOCHS, math.ceil(normals / NORMALS_PER_EPOCH))


def design_matrix(normals: np.ndarray, epochs: FitEpochs, material: brdf.BRDF) -> np.ndarray:
    """``A[e, n] = ρ(n, L_e, V_e) max(0, n·L_e) max(0, n·V_e) / d_e²`` (module docstring).

    Parameters
    ----------
    normals : (N, 3) float
        Unit normals, body frame.
    epochs : FitEpochs
    material : brdf.BRDF
        An isotropic registry model.

    Returns
    -------
    (E, N) float
        Flux ratio per m² of facet area.
    """
    if material.anisotropic:
        raise ValueError(f"{material.name} with nu ≠ nv needs facet tangents: give nu = nv")
    nl = epochs.light @ normals.T
    nv = epochs.view @ normals.T
    lv = np.sum(epochs.light * epochs.view, axis=1, keepdims=True)
    rho = material.from_cosines(nl, nv, lv)
    return rho * np.clip(nl, 0.0, None) * np.clip(nv, 0.0, None) * epochs.scale[:, None]


@dataclass(frozen=True)
class EGIFit:
    """An EGI fitted to light curves.

    Attributes
    ----------
    normals : (N, 3) float
        Unit normals, body frame.
    areas : (N,) float
        Facet areas (m², for the material's albedo).
    area_sigma : (N,) float
        1σ of the areas (m²): from the inverse normal matrix on the non-zero areas, that of
        a lone free area for the areas at 0; scaled by the reduced χ².
    material : brdf.BRDF
    model_flux : (E,) float
        Fitted flux ratio at the epochs.
    chi2 : float
        ``Σ ((F − F_obs)/σ)²`` of the data (without the smoothing term).
    smoothing : float
        Relative Tikhonov weight used.
    """

    normals: np.ndarray
    areas: np.ndarray
    area_sigma: np.ndarray
    material: brdf.BRDF
    model_flux: np.ndarray
    chi2: float
    smoothing: float

    @property
    def model_mag(self) -> np.ndarray:
        """(E,) fitted magnitudes."""
        return flux_to_magnitude(self.model_flux)

    def residual_rms_mag(self, epochs: FitEpochs) -> float:
        """rms of measured − fitted magnitudes (mag)."""
        return float(np.sqrt(np.mean((epochs.mag - self.model_mag) ** 2)))


def fit_egi(
    epochs: FitEpochs,
    material: brdf.BRDF,
    *,
    normals: int | np.ndarray = 1000,
    smoothing: float = 0.0,
    refinements: int = REFINEMENTS,
    polished: bool = True,
) -> EGIFit:
    """Non-negative least-squares EGI for a given material (module docstring).

    After the fit on the grid, each cluster of non-zero areas adds its area-weighted mean
    normal to the grid, the areas are refitted and the large facets polished off the grid
    (:func:`polish`), ``refinements`` times: faces between grid normals are then fitted by
    one normal at theirs.

    Parameters
    ----------
    epochs : FitEpochs
    material : brdf.BRDF
    normals : int or (N, 3) float
        Number of grid normals (:func:`normal_grid`) or the normals themselves.
    smoothing : float
        Relative weight of the Tikhonov smoothness term (0: none).
    refinements : int
        Rounds of cluster normals added to the grid.
    polished : bool
        Refine the large facets off the grid (:func:`polish`).

    Returns
    -------
    EGIFit
        Its normals are the grid's followed by those the last refinement added.

    Raises
    ------
    ValueError
        Fewer epochs than :func:`min_epochs`, or a negative or infinite smoothing.
    """
    grid = normal_grid(normals) if np.ndim(normals) == 0 else np.asarray(normals, float)
    check_epochs(len(epochs), len(grid))
    if not (math.isfinite(smoothing) and smoothing >= 0.0):
        raise ValueError(f"smoothing must be finite and ≥ 0, got {smoothing}")
    grid_design = design_matrix(grid, epochs, material)
    areas = solve_areas(grid_design, grid, epochs, smoothing)
    normals, design = grid, grid_design
    spacing = math.sqrt(4.0 * math.pi / len(grid))
    for _ in range(refinements):
        added, _ = cluster_normals(normals, areas, 2.0 * spacing)
        normals = np.vstack([grid, added])
        design = np.hstack([grid_design, design_matrix(added, epochs, material)])
        if smoothing > 0.0:
            areas = solve_areas(design, normals, epochs, smoothing, len(grid))
        else:  # the grid normals near the clusters, and the clusters' means
            near = _near(grid, added, 3.0 * spacing)
            local = np.concatenate([near, np.arange(len(grid), len(normals))])
            areas = np.zeros(len(normals))
            areas[local] = solve_areas(design[:, local], normals[local], epochs, 0.0)
        if polished:
            normals, areas = polish(normals, areas, epochs, material)
            design[:, areas > 0] = design_matrix(normals[areas > 0], epochs, material)
    return fit_result(normals, areas, design, epochs, material, smoothing)


def _near(grid: np.ndarray, centres: np.ndarray, radius: float) -> np.ndarray:
    """Indices of the grid normals within ``radius`` (chord) of any of ``centres``."""
    found = cKDTree(centres).query_ball_point(grid, radius, return_length=True)
    return np.flatnonzero(found > 0)


def solve_areas(
    design: np.ndarray,
    normals: np.ndarray,
    epochs: FitEpochs,
    smoothing: float,
    smoothed: int | None = None,
) -> np.ndarray:
    """Non-negative areas of the columns of ``design`` (normals ``normals``) under the
    closure rows and, with ``smoothing`` > 0, the smoothness term on the first ``smoothed``
    (default all) normals."""
    sigma = epochs.flux_sigma
    weighted = design / sigma[:, None]
    closure = math.sqrt(CLOSURE_WEIGHT * np.sum(weighted**2) / design.shape[1]) * normals.T
    system = np.vstack([weighted, closure])
    rhs = np.concatenate([epochs.flux / sigma, np.zeros(3)])
    if smoothing > 0.0:
        count = design.shape[1] if smoothed is None else smoothed
        operator = np.zeros((count, design.shape[1]))
        operator[:, :count] = smoothness_operator(normals[:count])
        weight = smoothing * np.sum(weighted**2) / np.sum(operator**2)
        system = np.vstack([system, math.sqrt(weight) * operator])
        rhs = np.concatenate([rhs, np.zeros(count)])
    # Columns scaled to unit norm (areas seen rarely and often alike); never-seen normals 0.
    norms = np.linalg.norm(system, axis=0)
    seen = norms > 0
    scaled, _ = nnls(system[:, seen] / norms[seen], rhs, maxiter=20 * design.shape[1])
    areas = np.zeros(design.shape[1])
    areas[seen] = scaled / norms[seen]
    return areas


def egi_residuals(epochs: FitEpochs, material: brdf.BRDF, normals: np.ndarray) -> np.ndarray:
    """Weighted flux residuals ``(F − F_obs)/σ`` (E,) of the non-negative EGI over the fixed
    ``normals`` (no refinement, no smoothing): the profile of the areas for given attitudes."""
    design = design_matrix(normals, epochs, material)
    areas = solve_areas(design, normals, epochs, 0.0)
    return (design @ areas - epochs.flux) / epochs.flux_sigma


def _chi2(model: np.ndarray, epochs: FitEpochs) -> float:
    """``Σ ((F − F_obs)/σ)²`` of model fluxes."""
    return float(np.sum(((model - epochs.flux) / epochs.flux_sigma) ** 2))


def fit_result(
    normals: np.ndarray,
    areas: np.ndarray,
    design: np.ndarray,
    epochs: FitEpochs,
    material: brdf.BRDF,
    smoothing: float,
) -> EGIFit:
    """The :class:`EGIFit` of ``areas`` over ``normals`` (``design`` their columns): model
    flux, χ² and the areas' 1σ."""
    model = design @ areas
    chi2 = _chi2(model, epochs)
    area_sigma = _area_sigma(design / epochs.flux_sigma[:, None], areas, chi2, len(epochs))
    return EGIFit(normals, areas, area_sigma, material, model, chi2, smoothing)


def _area_sigma(system: np.ndarray, areas: np.ndarray, chi2: float, count: int) -> np.ndarray:
    """1σ of the areas: ``√diag((J_pᵀ J_p)⁻¹) · √χ²_ν`` on the non-zero areas ``p``, and
    ``√(χ²_ν / (JᵀJ)_jj)`` (a lone free area) at the bound."""
    active = areas > 0
    dof = max(count - int(active.sum()), 1)
    reduced = max(chi2 / dof, 1.0)
    diagonal = np.sum(system**2, axis=0)
    with np.errstate(divide="ignore"):
        sigma = np.sqrt(reduced / diagonal)
    if np.any(active):
        normal = system[:, active].T @ system[:, active]
        sigma[active] = np.sqrt(np.clip(np.diag(np.linalg.pinv(normal)), 0.0, None) * reduced)
    return sigma


def polish(
    normals: np.ndarray,
    areas: np.ndarray,
    epochs: FitEpochs,
    material: brdf.BRDF,
    *,
    share: float = POLISH_SHARE,
) -> tuple[np.ndarray, np.ndarray]:
    """Directions and areas of the large facets refined by nonlinear least squares.

    The facets carrying at least ``share`` of the area move off the grid: their normals
    (two angles each, in the tangent plane) and log-areas minimise the magnitude residuals
    ``Σ ((m − m_obs)/σ)²`` (trust-region reflective, :func:`scipy.optimize.least_squares`),
    the small facets held. A grid of normals spaced ``δ`` apart misplaces a face by up to
    ``δ/2``, which changes its flux by a large fraction near the terminator. Each facet's
    flux depends on its own three parameters only, so the Jacobian costs three evaluations
    of the facets' columns (forward differences in the angles).

    Parameters
    ----------
    normals : (N, 3) float
    areas : (N,) float
    epochs : FitEpochs
    material : brdf.BRDF
    share : float
        Smallest fraction of the total area of a polished facet.

    Returns
    -------
    normals, areas
        With the polished facets' values replaced.
    """
    large = np.flatnonzero(areas >= share * areas.sum())
    if not len(large):
        return normals, areas
    held = np.where(areas >= share * areas.sum(), 0.0, areas)
    fixed = design_matrix(normals[held > 0], epochs, material) @ held[held > 0]
    start = normals[large]
    helper = np.where(np.abs(start[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    u = np.cross(start, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    frame = (u, np.cross(start, u))
    count, step = len(large), 1e-6

    def unpack(x: np.ndarray, shift: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        tilt = x[: 2 * count].reshape(-1, 2).copy()
        if shift is not None:
            tilt[:, shift] += step
        moved = start + tilt[:, :1] * frame[0] + tilt[:, 1:] * frame[1]
        return moved / np.linalg.norm(moved, axis=1, keepdims=True), np.exp(x[2 * count :])

    def columns(x: np.ndarray, shift: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        moved, sizes = unpack(x, shift)
        return design_matrix(moved, epochs, material), sizes

    def flux(x: np.ndarray) -> np.ndarray:
        design, sizes = columns(x)
        return np.maximum(fixed + design @ sizes, 1e-300)

    def residuals(x: np.ndarray) -> np.ndarray:
        return (flux_to_magnitude(flux(x)) - epochs.mag) / epochs.mag_err

    def jacobian(x: np.ndarray) -> np.ndarray:
        design, sizes = columns(x)
        scale = -2.5 / (math.log(10.0) * flux(x) * epochs.mag_err)
        jac = np.empty((len(epochs), 3 * count))
        for axis in (0, 1):
            shifted, _ = columns(x, axis)
            jac[:, axis : 2 * count : 2] = (shifted - design) / step * sizes
        jac[:, 2 * count :] = design * sizes
        return jac * scale[:, None]

    x0 = np.concatenate([np.zeros(2 * count), np.log(areas[large])])
    # A facet turns by at most ~17° and grows or shrinks by at most e³ within one polish.
    reach = np.concatenate([np.full(2 * count, 0.3), np.full(count, 3.0)])
    found = least_squares(
        residuals,
        x0,
        jac=jacobian,
        bounds=(x0 - reach, x0 + reach),
        method="trf",
        ftol=1e-6,
        max_nfev=POLISH_STEPS,
    )
    moved, sizes = unpack(found.x)
    normals, areas = normals.copy(), areas.copy()
    normals[large], areas[large] = moved, sizes
    return normals, areas


def cluster_normals(
    normals: np.ndarray, areas: np.ndarray, radius: float
) -> tuple[np.ndarray, np.ndarray]:
    """Area-weighted mean directions and total areas of the clusters of non-zero areas.

    A flat face whose normal falls between grid normals is fitted as a small cluster of
    neighbouring areas; its weighted mean is the face's normal to within the noise.

    Parameters
    ----------
    normals : (N, 3) float
    areas : (N,) float
    radius : float
        Normals closer than this (chord, ≈ rad) are in one cluster.

    Returns
    -------
    normals : (K, 3) float
        Unit mean normals of the K clusters.
    areas : (K,) float
        Their summed areas.
    """
    active = np.flatnonzero(areas > 0)
    pairs = cKDTree(normals[active]).query_pairs(radius, output_type="ndarray")
    graph = coo_matrix(
        (np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(active), len(active))
    )
    count, label = connected_components(graph, directed=False)
    sums = np.zeros((count, 3))
    np.add.at(sums, label, areas[active, None] * normals[active])
    return sums / np.linalg.norm(sums, axis=1, keepdims=True), np.bincount(label, areas[active])


#: The families :func:`fit_material` fits: the lobe's exponent (or width) parameter, its grid,
#: and the parameters tied to it.
LOBES: dict[str, tuple[str, tuple[float, ...], tuple[str, ...]]] = {
    "phong": ("n", (3.0, 10.0, 30.0, 100.0, 300.0), ()),
    "ashikhmin-shirley": ("nu", (3.0, 10.0, 30.0, 100.0, 300.0), ("nv",)),
    "cook-torrance": ("m", (0.05, 0.1, 0.2, 0.4, 0.8), ()),
}
#: Tolerance of the lobe's logarithm in :func:`fit_material`'s refinement between grid values.
LOBE_LOG_TOLERANCE = 0.05
#: The families :func:`fit_material` tries by default.
FITTED_FAMILIES = ("ashikhmin-shirley", "phong")


def fit_material(
    epochs: FitEpochs,
    families: Sequence[str] = FITTED_FAMILIES,
    *,
    normals: int = 1000,
    albedo: float = 0.2,
    smoothing: float = 0.0,
) -> EGIFit:
    """EGI with a fitted material: the specular weight ``rs`` and the lobe's exponent.

    The diffuse albedo ``rd`` is held at ``albedo`` (the flux fixes only the product of
    reflectance and area, so the absolute size rests on it); for each family, ``rs`` is found
    by Brent's method in its valid range for each exponent of :data:`LOBES` (and ``rs = 0``
    tried on its own), the lowest χ² kept over families and exponents; the best family's
    lobe is then refined by Brent's method on its logarithm between the grid values next to
    the best one (each trial lobe with its best ``rs``). The search fits each
    candidate on :data:`MATERIAL_SEARCH_NORMALS` normals (when ``normals`` is larger) with one
    refinement, then the EGI of the best material on ``normals``.

    Parameters
    ----------
    epochs : FitEpochs
    families : sequence of {"ashikhmin-shirley", "phong", "cook-torrance"}
        Registry names of the models tried (other parameters at their defaults). Phong
        with ``rs = 0`` is Lambert's model; Ashikhmin–Shirley's diffuse term is not.
    normals : int
        Normals of the final fit.
    albedo : float
        Assumed diffuse albedo ``rd``.
    smoothing : float
        Relative Tikhonov weight.

    Returns
    -------
    EGIFit
    """
    names = [brdf.describe(family).name for family in families]
    unknown = [name for name in names if name not in LOBES]
    if unknown or not names:
        raise ValueError(f"a fitted material is one of {', '.join(LOBES)}; got {unknown or names}")
    if not 0.0 < albedo < 1.0:
        raise ValueError(f"the assumed diffuse albedo rd must be in (0, 1), got {albedo}")
    check_epochs(len(epochs), normals)
    search = normal_grid(min(normals, MATERIAL_SEARCH_NORMALS))

    def chi2(rs: float, name: str, value: float) -> float:
        chosen = _lobe_material(name, albedo, rs, value)
        return fit_egi(epochs, chosen, normals=search, smoothing=smoothing, refinements=1).chi2

    def best_rs(name: str, value: float) -> tuple[float, float]:
        """The lowest χ² over ``rs`` at lobe ``value``, and that ``rs``."""
        top = 1.0 - albedo if brdf.describe(name).weights else 1.0
        found = minimize_scalar(
            chi2, bounds=(0.0, top), args=(name, value), method="bounded", options={"xatol": 0.01}
        )
        return float(found.fun), min(float(found.x), top)

    # (χ², rs, family, lobe): rs = 0 once per family, then the grid of lobes.
    tried = [(chi2(0.0, name, LOBES[name][1][0]), 0.0, name, LOBES[name][1][0]) for name in names]
    tried += [(*best_rs(name, value), name, value) for name in names for value in LOBES[name][1]]
    lowest, rs, name, value = min(tried, key=lambda item: item[0])
    if rs > 0.0:  # the lobe between the grid's neighbours of the best, by Brent on its log
        grid = LOBES[name][1]
        k = grid.index(value)
        span = (math.log(grid[max(k - 1, 0)]), math.log(grid[min(k + 1, len(grid) - 1)]))
        found = minimize_scalar(
            lambda log_value: best_rs(name, math.exp(log_value))[0],
            bounds=span,
            method="bounded",
            options={"xatol": LOBE_LOG_TOLERANCE},
        )
        if found.fun < lowest:
            value = math.exp(float(found.x))
            rs = best_rs(name, value)[1]
    return fit_egi(
        epochs, _lobe_material(name, albedo, rs, value), normals=normals, smoothing=smoothing
    )


def _lobe_material(name: str, albedo: float, rs: float, value: float) -> brdf.BRDF:
    """Model ``name`` with ``rd = albedo``, specular weight ``rs`` and lobe ``value``."""
    lobe, _, tied = LOBES[name]
    params = {"rd": albedo, "rs": max(rs, 0.0), lobe: value}
    return brdf.get(name, **params, **dict.fromkeys(tied, value))


def default_smoothing(epochs: FitEpochs) -> float:
    """The smoothness weight the geometry of ``epochs`` needs: :data:`BAND_SMOOTHING` when
    the data see the normals along one band, else 0.

    The spread is the smallest eigenvalue of ``Σ_e h_e h_eᵀ / E``, ``h`` the unit bisector
    of the body-frame Sun and observer directions (the normal a face must have to be seen
    best): near 1/3 for a tumbling object, near 0 for a stabilised one, whose observer
    stays fixed in its body frame while the Sun sweeps one arc. Non-negativity and closure
    regularise a fit that sees every direction; on one band they let the fit put area of
    any size on normals the data hardly see (fits of a 22 m² box to a stabilised night
    reached 10⁴–10⁶ m²), and the smoothness term keeps it off them (docs/shape.md,
    "Regularisation").
    """
    bisector = epochs.light + epochs.view
    bisector /= np.maximum(np.linalg.norm(bisector, axis=1, keepdims=True), 1e-12)
    spread = np.linalg.eigvalsh(bisector.T @ bisector / len(bisector))[0]
    return BAND_SMOOTHING if spread < BAND_SPREAD else 0.0


def check_epochs(count: int, normals: int) -> None:
    """ValueError when ``count`` epochs cannot support an EGI of ``normals`` normals."""
    need = min_epochs(normals)
    if count < need:
        raise ValueError(
            f"{count} epochs cannot support an EGI of {normals} normals (need at least "
            f"{need}: max({MIN_EPOCHS}, normals/{NORMALS_PER_EPOCH})); give more data or fewer "
            "--normals"
        )


def bootstrap_areas(epochs: FitEpochs, fit: EGIFit, *, samples: int, seed: int) -> np.ndarray:
    """EGIs refitted to the fitted light curve plus fresh noise (parametric bootstrap).

    Each sample draws ``m* = m_fit + σ_mag z`` (``z`` standard normal, seeded) and refits
    the areas over the fit's normals (grid, cluster and polished ones) with its material.

    Parameters
    ----------
    epochs : FitEpochs
    fit : EGIFit
    samples : int
    seed : int

    Returns
    -------
    (samples, N) float
        Areas (m²).
    """
    rng = np.random.default_rng(seed)
    design = design_matrix(fit.normals, epochs, fit.material)
    out = np.empty((samples, len(fit.normals)))
    for k in range(samples):
        drawn = fit.model_mag + epochs.mag_err * rng.standard_normal(len(epochs))
        noisy = replace(epochs, mag=drawn)
        out[k] = solve_areas(design, fit.normals, noisy, 0.0)
    return out
