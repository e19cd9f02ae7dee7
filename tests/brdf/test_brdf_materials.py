"""Material presets in brdf/data/materials.toml."""

import pytest

import brdf


def test_presets_cover_the_required_materials_with_sources():
    presets = brdf.materials.load_presets()
    required = {
        "solar-cell",
        "mli-kapton",
        "white-paint",
        "aluminium",
        "black-paint",
        "starlink-chassis",
        "starlink-solar-array",
    }
    assert required <= set(presets)
    for name, preset in presets.items():
        model, params, source = preset  # (model name, params, source)
        assert model in brdf.available(), name
        assert len(source) > 20, name
        assert preset.brdf().params == params
    assert "fitted to" in presets["starlink-chassis"].source
    assert presets["white-paint"].brdf()([0, 0, 1], [0, 0, 1], [0, 0, 1]) == pytest.approx(
        0.8 / 3.141592653589793
    )


@pytest.mark.parametrize(
    ("text", "fragments"),
    [
        (
            '[paint]\nmodel = "lambert"\nparams = { rd = 1.5 }\nsource = "x"\n',
            ["material 'paint'", "'rd'", "0 ≤ rd ≤ 1"],
        ),
        ('[paint]\nmodel = "lambert"\nparams = { rd = 0.5 }\n', ["'paint'", "source"]),
        ('[paint\nmodel = "lambert"\n', ["presets.toml"]),
    ],
)
def test_bad_presets_name_the_file_and_material(tmp_path, text, fragments):
    path = tmp_path / "presets.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ValueError) as error:
        brdf.materials.load_presets(path)
    assert "presets.toml" in str(error.value)
    for fragment in fragments:
        assert fragment in str(error.value)
