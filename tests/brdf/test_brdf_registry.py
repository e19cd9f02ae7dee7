"""The registry: names, descriptions, validation messages, the BRDF object."""

import numpy as np
import pytest
import torch

import brdf


def test_available_and_describe():
    assert brdf.available() == (
        "lambert",
        "phong",
        "cook-torrance",
        "ashikhmin-shirley",
        "lommel-seeliger",
        "two-lobe",
    )
    info = brdf.describe("cook_torrance")  # "_" accepted for "-"
    assert info.name == "cook-torrance"
    assert info.parameter_names == ("rd", "rs", "m", "f0")
    assert info.parameter("m").range_text == "0 < m"
    assert info.parameter("f0").range_text == "0 ≤ f0 ≤ 1"
    assert brdf.describe("lommel-seeliger").parameter("k").range_text == "k any real number"
    text = str(brdf.describe("phong"))
    assert "rd + rs ≤ 1" in text and "specular exponent" in text


def test_get_fills_defaults_and_keeps_given_values():
    model = brdf.get("ASHIKHMIN_SHIRLEY", rs=0.2)
    defaults = {p.name: p.default for p in brdf.describe("ashikhmin-shirley").parameters}
    assert model.name == "ashikhmin-shirley"
    assert model.params == {**defaults, "rs": 0.2}
    assert not model.anisotropic


@pytest.mark.parametrize(
    ("name", "params", "fragments"),
    [
        ("lambert", {"rd": -0.1}, ["'rd'", "0 ≤ rd ≤ 1"]),
        ("phong", {"rd": 0.6, "rs": 0.5}, ["rd + rs = 1.1", "exceeds 1"]),
        ("phong", {"n": -1.0}, ["'n'", "0 ≤ n"]),
        ("cook-torrance", {"rd": 0.7, "rs": 0.4}, ["rd + rs"]),
        ("cook-torrance", {"m": 0.0}, ["'m'", "0 < m"]),
        ("cook-torrance", {"f0": 1.2}, ["'f0'", "0 ≤ f0 ≤ 1"]),
        ("ashikhmin-shirley", {"nu": -5.0}, ["'nu'", "0 ≤ nu"]),
        ("lommel-seeliger", {"d": 0.0}, ["'d'", "0 < d"]),
        ("lommel-seeliger", {"w": float("nan")}, ["'w'", "0 ≤ w"]),
        ("phong", {"shininess": 3.0}, ["unknown parameter", "shininess", "rd, rs, n"]),
        ("oren-nayar", {}, ["unknown BRDF model", "lambert, phong, cook-torrance"]),
    ],
)
def test_invalid_parameters_are_rejected_with_the_range(name, params, fragments):
    with pytest.raises(brdf.BRDFParameterError) as error:
        brdf.get(name, **params)
    assert isinstance(error.value, ValueError)
    for fragment in fragments:
        assert fragment in str(error.value)


def test_ashikhmin_shirley_allows_rd_plus_rs_above_one():
    # Its diffuse term carries (1 − rs): no joint constraint.
    assert brdf.get("ashikhmin-shirley", rd=0.9, rs=0.9).params["rd"] == 0.9


def test_array_and_tensor_parameters_are_validated_elementwise():
    model = brdf.get("phong", rd=np.array([0.1, 0.2]), rs=np.array([0.3, 0.4]), n=10.0)
    assert model.params["rd"].shape == (2,)
    with pytest.raises(brdf.BRDFParameterError, match=r"index \[2\]"):
        brdf.get("lambert", rd=np.array([0.1, 0.2, 1.5]))
    with pytest.raises(brdf.BRDFParameterError, match="'m'"):
        brdf.get("cook-torrance", m=torch.tensor([0.1, -0.2], requires_grad=True))


def test_anisotropic_model_needs_the_tangent_frame():
    model = brdf.get("ashikhmin-shirley", nu=10.0, nv=1000.0)
    assert model.anisotropic
    normal, light, view = [0.0, 0.0, 1.0], [0.0, 0.6, 0.8], [0.0, -0.6, 0.8]
    with pytest.raises(ValueError, match="tangent"):
        model(normal, light, view)
    with pytest.raises(ValueError, match="hu and hv"):
        model.from_cosines(0.8, 0.8, 0.28)
    value = model(normal, light, view, tangent=[1.0, 0.0, 0.0])
    assert value > 0


def test_brdf_object_evaluates_its_model():
    model = brdf.get("phong", rd=0.3, rs=0.4, n=15.0)
    normal, light, view = [0.0, 0.0, 1.0], [0.0, 0.6, 0.8], [0.3, -0.6, 0.74]
    view = np.array(view) / np.linalg.norm(view)
    assert model(normal, light, view) == brdf.phong(normal, light, view, 0.3, 0.4, 15.0)
