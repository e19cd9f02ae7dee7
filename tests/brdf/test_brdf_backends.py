"""The kernel interface: numpy vs torch, dtypes, autograd, broadcasting."""

import numpy as np
import pytest
import torch

import brdf

COSINE_FORMS = {
    "lambert": brdf.lambert_from_cosines,
    "phong": brdf.phong_from_cosines,
    "cook-torrance": brdf.cook_torrance_from_cosines,
    "ashikhmin-shirley": brdf.ashikhmin_shirley_from_cosines,
    "lommel-seeliger": brdf.lommel_seeliger_from_cosines,
    "two-lobe": brdf.two_lobe_from_cosines,
}


def _cases(parameter_sets):
    return [(name, params) for name, sets in parameter_sets.items() for params in sets]


def test_vector_form_matches_independent_reference(parameter_sets, random_geometry, reference):
    normal, light, view, tangent = random_geometry(np.random.default_rng(5), 400, True)
    for name, params in _cases(parameter_sets):
        model = brdf.get(name, **params)
        values = model(normal, light, view, tangent=tangent)
        use_tangent = model.anisotropic
        expected = [
            reference(name, n, ell, v, params, t if use_tangent else None)
            for n, ell, v, t in zip(normal, light, view, tangent, strict=True)
        ]
        np.testing.assert_allclose(values, expected, rtol=1e-9, atol=1e-300, err_msg=name)


def test_numpy_and_torch_agree_in_float64(parameter_sets, random_geometry):
    normal, light, view, tangent = random_geometry(np.random.default_rng(6), 10_000)
    as_tensor = torch.from_numpy
    for name, params in _cases(parameter_sets):
        model = brdf.get(name, **params)
        numpy_values = model(normal, light, view, tangent=tangent)
        torch_values = model(*map(as_tensor, (normal, light, view)), tangent=as_tensor(tangent))
        assert isinstance(torch_values, torch.Tensor) and torch_values.dtype == torch.float64
        # numpy's and torch's exp/pow kernels (vectorised per CPU) differ in the last bits,
        # which large arguments amplify (m = 0.05, exponents to 1000, the phase function's
        # exp(−α/d)): up to 2.5e-13 relative measured.
        np.testing.assert_allclose(
            torch_values.numpy(), numpy_values, rtol=1e-10, atol=1e-300, err_msg=name
        )


def test_float32_is_kept_and_close_to_float64(parameter_sets, random_geometry):
    normal, light, view, tangent = random_geometry(np.random.default_rng(7), 2000, True)
    for name, params in _cases(parameter_sets):
        model = brdf.get(name, **params)
        exact = model(normal, light, view, tangent=tangent)
        single = [normal.astype(np.float32), light.astype(np.float32), view.astype(np.float32)]
        numpy32 = model(*single, tangent=tangent.astype(np.float32))
        torch32 = model(*map(torch.from_numpy, single), tangent=torch.from_numpy(tangent).float())
        assert numpy32.dtype == np.float32 and torch32.dtype == torch.float32
        # Lobes of exponent e amplify the float32 rounding of N·H by e (here up to 2000).
        scale = exact.max()
        np.testing.assert_allclose(numpy32, exact, rtol=2e-3, atol=1e-5 * scale, err_msg=name)
        np.testing.assert_allclose(torch32.numpy(), exact, rtol=2e-3, atol=1e-5 * scale)


def test_per_facet_parameters_broadcast_over_epochs():
    rng = np.random.default_rng(8)
    epochs, facets = 7, 5
    nl = rng.uniform(-0.2, 1, (epochs, facets))
    nv = rng.uniform(-0.2, 1, (epochs, facets))
    lv = rng.uniform(-0.9, 1, (epochs, 1))
    rd = rng.uniform(0, 0.4, facets)
    rs = rng.uniform(0, 0.5, facets)
    exponent = rng.uniform(1, 300, facets)
    values = brdf.ashikhmin_shirley_from_cosines(nl, nv, lv, rd=rd, rs=rs, nu=exponent, nv=exponent)
    assert values.shape == (epochs, facets)
    for f in range(facets):
        column = brdf.ashikhmin_shirley_from_cosines(
            nl[:, f], nv[:, f], lv[:, 0], rd=rd[f], rs=rs[f], nu=exponent[f], nv=exponent[f]
        )
        np.testing.assert_allclose(values[:, f], column, rtol=1e-14)
    # Parameter tensors with numpy cosines give a tensor (the renderer's autograd path).
    as_tensor = brdf.phong_from_cosines(nl, nv, lv, torch.tensor(rd), 0.5, 20.0)
    assert isinstance(as_tensor, torch.Tensor) and as_tensor.shape == (epochs, facets)


def test_object_cosine_form_matches_vector_form(parameter_sets, random_geometry):
    normal, light, view, tangent = random_geometry(np.random.default_rng(9), 1000)
    for name, params in _cases(parameter_sets):
        model = brdf.get(name, **params)
        nl, nv, lv = (
            np.sum(a * b, -1) for a, b in ((normal, light), (normal, view), (light, view))
        )
        u = tangent - np.sum(tangent * normal, -1, keepdims=True) * normal
        u /= np.linalg.norm(u, axis=-1, keepdims=True)
        half = (light + view) / np.linalg.norm(light + view, axis=-1, keepdims=True)
        hu, hv = np.sum(half * u, -1), np.sum(half * np.cross(normal, u), -1)
        np.testing.assert_allclose(
            model.from_cosines(nl, nv, lv, hu=hu, hv=hv),
            model(normal, light, view, tangent=tangent),
            rtol=1e-12,
            atol=1e-300,
        )


def _visible_cosines(count, seed):
    """Cosines of random visible geometries away from the grazing and mirror limits."""
    rng = np.random.default_rng(seed)
    normal = np.array([0.0, 0.0, 1.0])
    zenith = rng.uniform(0.1, 1.3, (2, count))
    azimuth = rng.uniform(0, 2 * np.pi, (2, count))
    light, view = (
        np.stack([np.sin(z) * np.cos(a), np.sin(z) * np.sin(a), np.cos(z)], -1)
        for z, a in zip(zenith, azimuth, strict=True)
    )
    half = (light + view) / np.linalg.norm(light + view, axis=-1, keepdims=True)
    return [
        torch.tensor(x)
        for x in (light @ normal, view @ normal, np.sum(light * view, -1), half[:, 0], half[:, 1])
    ]


@pytest.mark.parametrize("name", list(COSINE_FORMS))
def test_autograd_matches_finite_differences(name, parameter_sets):
    nl, nv, lv, hu, hv = _visible_cosines(12, seed=10)
    params = parameter_sets[name][-1]
    names = list(params)
    extra = {"hu": hu, "hv": hv} if name == "ashikhmin-shirley" else {}

    def function(*values):
        return COSINE_FORMS[name](nl, nv, lv, **dict(zip(names, values, strict=True)), **extra)

    inputs = tuple(
        torch.tensor(float(params[n]), dtype=torch.float64, requires_grad=True) for n in names
    )
    assert torch.autograd.gradcheck(function, inputs, eps=1e-6, atol=1e-7, rtol=1e-5)
    # Gradients with respect to the geometry as well (the renderer differentiates attitude).
    geometry = tuple(x.clone().requires_grad_(True) for x in (nl, nv))
    assert torch.autograd.gradcheck(
        lambda a, b: COSINE_FORMS[name](a, b, lv, **params, **extra),
        geometry,
        eps=1e-7,
        atol=1e-6,
        rtol=1e-5,
    )


@pytest.mark.parametrize("name", list(COSINE_FORMS))
def test_no_nan_gradients_at_masked_geometries(name, parameter_sets):
    # Below the horizon, on it, L = −V, L = V, and a visible one for reference.
    nl = torch.tensor([-0.5, 0.0, 0.6, 0.7, 1.0, 0.3], dtype=torch.float64, requires_grad=True)
    nv = torch.tensor([0.5, 0.4, -0.6, 0.0, 1.0, 0.8], dtype=torch.float64, requires_grad=True)
    lv = torch.tensor([0.0, 0.2, -1.0, 0.5, 1.0, 0.1], dtype=torch.float64)
    hu = torch.tensor([0.0, 0.1, 0.0, 0.3, 0.0, 0.2], dtype=torch.float64)
    hv = torch.tensor([0.0, 0.2, 0.0, 0.1, 0.0, 0.1], dtype=torch.float64)
    params = {
        k: torch.tensor(float(v), dtype=torch.float64, requires_grad=True)
        for k, v in parameter_sets[name][-1].items()
    }
    extra = {"hu": hu, "hv": hv} if name == "ashikhmin-shirley" else {}
    rho = COSINE_FORMS[name](nl, nv, lv, **params, **extra)
    assert torch.all(rho[:4] == 0) and rho[4] > 0
    rho[:4].sum().backward()
    for tensor in (nl, nv, *params.values()):
        if tensor.grad is not None:  # None: ρ does not depend on it (Lambert's nl, nv)
            assert torch.all(torch.isfinite(tensor.grad)), name
            assert torch.all(tensor.grad == 0), name
