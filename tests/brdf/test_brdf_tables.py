"""The Starlink lab-table reader and BRDFTable."""

from pathlib import Path

import numpy as np
import pytest

import brdf

STARLINK = Path(__file__).resolve().parents[2] / "data" / "starlink"  # real data, not package data
HEADER = """# (phi_i, theta_i) are the zenith and azimuth angles
# of ingoing light
# (phi_o, theta_o) are the zenith and azimuth angles
# of scattered light
#
# phi_i     theta_i     phi_o     theta_o     brdf
"""


@pytest.mark.parametrize("material", ["chassis", "solar_array"])
def test_reads_the_lab_tables_with_their_angle_convention(material):
    table = brdf.read_starlink_table(STARLINK / f"{material}_brdf.csv")
    assert len(table) == 724 and table.source == f"{material}_brdf.csv"
    assert set(np.unique(table.zenith_in)) == {5.0, 41.4, 60.0, 75.0}
    assert np.all(table.azimuth_in == -180.0) and np.all(table.azimuth_out == 0.0)
    light, view = table.directions()
    normal = np.array([0.0, 0.0, 1.0])
    for incidence in np.unique(table.zenith_in):
        scan = np.flatnonzero(table.zenith_in == incidence)
        peak = scan[np.argmax(table.value[scan])]
        # The specular peak lies at the mirror direction of the source: zenith read from the
        # phi columns, azimuth from the theta columns.
        mirror = 2 * (light[peak] @ normal) * normal - light[peak]
        assert np.degrees(np.arccos(min(1.0, mirror @ view[peak]))) <= 1.0


def test_negative_zenith_is_the_opposite_azimuth():
    table = brdf.BRDFTable.from_columns(
        {
            "zenith_in": [30.0],
            "azimuth_in": [0.0],
            "zenith_out": [-40.0],
            "azimuth_out": [0.0],
            "value": [1.0],
        }
    )
    other = brdf.BRDFTable.from_columns(
        {
            "zenith_in": [30.0],
            "azimuth_in": [0.0],
            "zenith_out": [40.0],
            "azimuth_out": [180.0],
            "value": [1.0],
        }
    )
    np.testing.assert_allclose(table.directions()[1], other.directions()[1], atol=1e-15)


@pytest.mark.parametrize(
    ("body", "fragments"),
    [
        (
            HEADER + "75.0 -180.0 -90.0 0.0 1e-4\n75.0 -180.0 x 0.0 1e-4\n",
            ["line 8", "column phi_o", "'x'"],
        ),
        (HEADER + "75.0 -180.0 -90.0 0.0\n", ["line 7", "4 fields, expected 5"]),
        (HEADER + "75.0 -180.0 -90.0 0.0 -2.0\n", ["line 7", "column brdf"]),
        (HEADER.replace("zenith and azimuth", "angles"), ["does not state"]),
        (HEADER, ["no data lines"]),
    ],
)
def test_bad_tables_name_file_line_and_column(tmp_path, body, fragments):
    path = tmp_path / "bad_brdf.csv"
    path.write_text(body, encoding="utf-8")
    with pytest.raises(brdf.BRDFTableError) as error:
        brdf.read_starlink_table(path)
    assert "bad_brdf.csv" in str(error.value)
    for fragment in fragments:
        assert fragment in str(error.value)


def test_from_columns_validates():
    with pytest.raises(brdf.BRDFTableError, match="missing column"):
        brdf.BRDFTable.from_columns({"zenith_in": [1.0]})
    with pytest.raises(brdf.BRDFTableError, match="row 1, column value"):
        brdf.BRDFTable.from_columns(
            {
                "zenith_in": [1, 2],
                "azimuth_in": [0, 0],
                "zenith_out": [3, 4],
                "azimuth_out": [0, 0],
                "value": [1.0, np.nan],
            }
        )
