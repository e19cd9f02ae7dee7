"""Reflectance models (BRDFs) for facet light curves; a leaf package (numpy + torch only).

Models (``docs/brdf.md`` gives the exact forms): Lambert, energy-normalised Phong,
Cook–Torrance, Ashikhmin–Shirley, Lommel–Seeliger (DAMIT) and a two-lobe microfacet model
(broad glossy lobe plus narrow mirror lobe, for glints). Each has a vector form of unit
``(..., 3)`` directions and a fast cosine form of ``n·L``, ``n·V`` and ``L·V`` for the renderer;
both accept numpy arrays or torch tensors (float32/float64, differentiable in the parameters).

>>> import brdf
>>> model = brdf.get("cook-torrance", rd=0.2, rs=0.6, m=0.3, f0=0.9)
>>> rho = model([0, 0, 1], [0, 0.6, 0.8], [0, -0.6, 0.8])   # sr⁻¹

Modules
-------
- :mod:`~brdf.ashikhmin_shirley` — Anisotropic Phong reflectance of Ashikhmin & Shirley (2000).
- :mod:`~brdf.cook_torrance` — Cook–Torrance microfacet reflectance (Cook & Torrance 1981).
- :mod:`~brdf.fitting` — Least-squares fits of reflectance-model parameters to tabulated BRDF
  measurements.
- :mod:`~brdf.lambert` — Lambertian (perfectly diffuse) reflectance.
- :mod:`~brdf.lommel_seeliger` — Lommel–Seeliger + Lambert scattering with the DAMIT phase
  function, for asteroids.
- :mod:`~brdf.materials` — Material presets: named reflectance models with parameters and their
  sources.
- :mod:`~brdf.phong` — Energy-normalised Phong reflectance (Phong 1975; Lewis 1994
  normalisation).
- :mod:`~brdf.quadrature` — Numerical checks of a BRDF: directional-hemispherical albedo and
  Helmholtz reciprocity.
- :mod:`~brdf.registry` — Registry of the reflectance models: names, parameters, valid ranges
  and the `BRDF` object.
- :mod:`~brdf.tables` — Tabulated BRDF measurements (incidence and scatter angles → value) and
  the lab-table reader.
- :mod:`~brdf.two_lobe` — Diffuse term plus two microfacet lobes: a broad glossy lobe and a
  narrow mirror (glint) lobe.
"""

from brdf import materials
from brdf.ashikhmin_shirley import ashikhmin_shirley, ashikhmin_shirley_from_cosines
from brdf.cook_torrance import cook_torrance, cook_torrance_from_cosines
from brdf.fitting import FitResult, fit, mirror_band_weights, mirror_distance_deg
from brdf.lambert import lambert, lambert_from_cosines
from brdf.lommel_seeliger import lommel_seeliger, lommel_seeliger_from_cosines, phase_function
from brdf.phong import phong, phong_from_cosines
from brdf.quadrature import albedo, reciprocity_error
from brdf.registry import (
    BRDF,
    BRDFParameterError,
    ModelInfo,
    ParameterSpec,
    available,
    describe,
    get,
)
from brdf.tables import BRDFTable, BRDFTableError, read_starlink_table
from brdf.two_lobe import two_lobe, two_lobe_from_cosines

__all__ = [
    "BRDF",
    "BRDFParameterError",
    "BRDFTable",
    "BRDFTableError",
    "FitResult",
    "ModelInfo",
    "ParameterSpec",
    "albedo",
    "ashikhmin_shirley",
    "ashikhmin_shirley_from_cosines",
    "available",
    "cook_torrance",
    "cook_torrance_from_cosines",
    "describe",
    "fit",
    "get",
    "lambert",
    "lambert_from_cosines",
    "lommel_seeliger",
    "lommel_seeliger_from_cosines",
    "materials",
    "mirror_band_weights",
    "mirror_distance_deg",
    "phase_function",
    "phong",
    "phong_from_cosines",
    "read_starlink_table",
    "reciprocity_error",
    "two_lobe",
    "two_lobe_from_cosines",
]
