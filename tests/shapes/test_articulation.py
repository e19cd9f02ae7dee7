"""Articulated parts: manifest parsing and validation, joint angles and poses."""

import numpy as np
import pytest

from shapes import ShapeError, get_library, primitives
from shapes.articulation import ArticulatedModel, Articulation, Joint, axis_rotation

GROUPS = ["bus", "solar_array", "array_back", "yoke"]


def _tracking(**joint):
    spec = {"kind": "sun_tracking", "axis": [0, 1, 0], "normal": [1, 0, 0], **joint}
    return [{"name": "arrays", "groups": ["solar_array", "array_back"], "joint": spec}]


@pytest.mark.parametrize(
    ("parts", "message"),
    [
        (_tracking(axis=[0, 0, 0]), "axis [0.0, 0.0, 0.0] has zero length"),
        ([{"name": "a", "groups": ["bus"], "joint": {"kind": "hinge"}}], "unknown joint kind"),
        ([{"name": "a", "groups": ["wing"], "joint": {"kind": "fixed"}}], "group 'wing'"),
        (_tracking(limits_deg=[10, -10]), "low ≤ high"),
        (_tracking(normal=[0, 2, 0]), "parallel to the axis"),
        (_tracking(speed=3), "unknown field(s) speed"),
        (
            [{"name": "a", "groups": ["bus"], "joint": {"kind": "scheduled", "axis": [1, 0, 0]}}],
            "needs a column",
        ),
        (_tracking() + _tracking(), "part name used twice"),
        ([], "non-empty list"),
    ],
)
def test_invalid_parts_give_one_line_errors(parts, message):
    with pytest.raises(ShapeError) as info:
        Articulation.from_list(parts, GROUPS, "lib: shape 'x'")
    text = str(info.value)
    assert message in text and "\n" not in text and text.startswith("lib: shape 'x'")


def test_manifest_form_round_trips():
    parts = _tracking(limits_deg=[-90, 45], offset_deg=5, pivot=[0, 1, 0])
    first = Articulation.from_list(parts, GROUPS, "x")
    again = Articulation.from_list(first.to_list(), GROUPS, "x")
    assert again.to_list() == first.to_list()
    assert first.to_list()[0]["joint"]["limits_deg"] == [-90.0, 45.0]


def test_sun_tracking_maximises_the_sun_cosine_within_limits():
    rng = np.random.default_rng(20261201)
    sun = rng.normal(size=(200, 3))
    for limits in ([-180.0, 180.0], [-60.0, 120.0]):
        joint = Joint.from_dict(
            {"kind": "sun_tracking", "axis": [0, 1, 0], "normal": [1, 0, 0], "limits_deg": limits},
            "x",
        )
        angle = joint.angles(sun, None, "x")
        assert np.all((angle >= limits[0]) & (angle <= limits[1]))
        normal = np.einsum("eij,j->ei", axis_rotation(joint.axis, np.radians(angle)), joint.normal)
        cosine = np.sum(normal * sun, axis=1) / np.linalg.norm(sun, axis=1)
        search = np.radians(np.linspace(limits[0], limits[1], 7201))
        brute = (
            np.einsum("gij,j->gi", axis_rotation(joint.axis, search), joint.normal)
            @ (sun / np.linalg.norm(sun, axis=1, keepdims=True)).T
        ).max(axis=0)
        assert np.all(cosine >= brute - 1e-5)


def test_offset_and_clip_to_the_nearer_limit():
    joint = Joint.from_dict(
        {
            "kind": "sun_tracking",
            "axis": [0, 1, 0],
            "normal": [1, 0, 0],
            "limits_deg": [-150, -30],
            "offset_deg": 10,
        },
        "x",
    )
    # Sun along +x → ideal 0, +10 offset → 10: nearer limit is −30 (40° away, −150 is 160°)
    assert joint.angles(np.array([1.0, 0, 0]), None, "x") == pytest.approx(-30.0)
    # Sun along −x → ideal 180 (+10 = 190 ≡ −170): nearer limit −150
    assert joint.angles(np.array([-1.0, 0, 0]), None, "x") == pytest.approx(-150.0)


def test_scheduled_joint_reads_its_column_and_rejects_angles_beyond_limits():
    joint = Joint.from_dict(
        {"kind": "scheduled", "axis": [0, 0, 1], "column": "drive_deg", "limits_deg": [0, 90]},
        "shape 'x', part 'p'",
    )
    angles = joint.angles(np.zeros((3, 3)), {"drive_deg": np.array([0.0, 45.0, 90.0])}, "p")
    assert angles.tolist() == [0.0, 45.0, 90.0]
    with pytest.raises(ShapeError, match="column 'drive_deg', row 2"):
        joint.angles(np.zeros((2, 3)), {"drive_deg": np.array([10.0, 95.0])}, "p")
    with pytest.raises(ShapeError, match="needs column 'drive_deg'"):
        joint.angles(np.zeros((2, 3)), {}, "p")


def test_posed_model_turns_only_the_moving_part():
    model = primitives.box_wing()
    shape = ArticulatedModel(model, Articulation.from_list(_tracking(), model.group_names, "x"))
    posed = shape.posed(axis_rotation(np.array([0.0, 1.0, 0.0]), np.radians([90.0])))
    cells = model.group_names.index("solar_array")
    bus = model.group_names.index("bus")
    # the cell side's normal +x turns to −z (rotation by 90° about +y); the bus stays
    assert np.allclose(posed.normals[model.group_index == cells], [0.0, 0.0, -1.0])
    assert np.allclose(
        posed.normals[model.group_index == bus], model.normals[model.group_index == bus]
    )
    groups = shape.rigid_groups()
    assert [len(g.faces) for g in groups] == [
        int(np.sum(model.group_index == bus)) + int(np.sum(model.group_index == 3)),
        int(np.sum(np.isin(model.group_index, [cells, 2]))),
    ]


def test_builtin_tracking_box_wing_loads_articulated():
    shape = get_library().load("box_wing_tracking", articulated=True, visibility=False)
    assert isinstance(shape, ArticulatedModel)
    assert shape.articulation.names == ["arrays"]
    assert shape.articulation.parts[0].joint.kind == "sun_tracking"
    rigid = get_library().load("box_wing_tracking", visibility=False)
    assert not isinstance(rigid, ArticulatedModel) and len(rigid.faces) == 44
