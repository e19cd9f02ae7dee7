"""Photometric attitude inversion: the programmatic API behind ``lightcurve invert``.

:func:`invert` estimates the attitude, body rates (and optionally inertia ratios,
albedo–area scale and shape) of an object from one light curve with one of three
estimators (``docs/inversion.md`` has the equations and measured figures):

``"ukf"``
    One shape. A batch maximum-a-posteriori fit of the initial state on the first part
    of the data (:mod:`filters.global_search`: prior-centred screening and batched
    Levenberg–Marquardt; uniform on SO(3) without ``q0``), then the USQUE attitude UKF
    (:mod:`filters.ukf`) on the rest, its measurement variance widened by the model error
    it estimates online; then its hypotheses refitted on the whole arc together with the
    model adjustments of ``estimate`` (inertia, tilt of the principal axes, albedo–area
    scale, stretch, materials: :class:`~lightcurve.photometry.adjusted.AdjustableShape`).
``"mmae"``
    Several shapes: the same initial fit per shape, then a bank of UKFs with model
    probabilities, the fused attitude and a consistency test (:mod:`filters.mmae`); the
    same whole-arc refit of every shape, weighed by its Laplace evidence, reports the
    shape, the adjustments and ``none_fits`` (no shape within ``model_tolerance_mag``).
``"pf"``
    One or several shapes, with or without a prior: global search of the initial state
    (uniform on SO(3), rates in a ball, shape index per candidate), particles seeded
    around the best distinct candidates, then the regularised particle filter with
    tempering (:mod:`filters.particle`); the result lists the posterior modes with their
    symmetry-equivalent attitudes.

Every estimator runs on :class:`~lightcurve.photometry.measurement.PhotometricModel`. The result,
:class:`InversionResult`, holds the final state at the LAST measurement epoch and a table
of per-epoch estimates.

Modules: ``options`` (:class:`InversionOptions`, which options each method reads,
:func:`validate_request`), ``context`` (what one run shares, input checks), ``search`` (the
initial-state search), ``epochs`` (the per-epoch filtering loop and its table rows),
``bank`` (UKF/MMAE), ``model_fit`` (state and model adjustments fitted on the whole arc),
``refit`` (the UKF/MMAE hypotheses refitted with it, the shapes weighed), ``particles``
(PF), ``polish`` (PF modes refined on the whole arc),
``result`` (:class:`InversionResult`) and ``driver`` (:func:`invert` and :data:`RUNNERS`,
the table of methods).

Conventions: quaternions scalar-last, ``A(q)`` inertial → body, sign-canonical
(``q4 ≥ 0``); rates in rad/s in the body frame; ``attitude_sigma_deg`` is the total 1σ
attitude uncertainty ``√(tr P_δθ)`` in degrees (``P_δθ`` the covariance of the body-frame
attitude-error vector); ``sigma_att_x/y/z`` in the table are its per-axis square roots.
"""

from lightcurve.inversion.context import MIN_MEASUREMENTS, batch_problem, shape_symmetry
from lightcurve.inversion.driver import RUNNERS, invert
from lightcurve.inversion.options import (
    FILTER_REFINE_KEEP,
    METHOD_OPTIONS,
    METHODS,
    PF_REFINE_KEEP,
    InversionOptions,
    validate_request,
)
from lightcurve.inversion.result import InversionResult

__all__ = [
    "FILTER_REFINE_KEEP",
    "METHODS",
    "METHOD_OPTIONS",
    "MIN_MEASUREMENTS",
    "PF_REFINE_KEEP",
    "RUNNERS",
    "InversionOptions",
    "InversionResult",
    "batch_problem",
    "invert",
    "shape_symmetry",
    "validate_request",
]
