"""A robot declared in a YAML file: the same facts as a registered one, and one line naming file and field per
mistake."""

import dataclasses
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robots.measured_reach import reach_m_of
from robots.registry import get_robot, is_available, register_file
from robots.robot_file import RobotFileError, load_robot_file
from tests.wrong_values import WRONG, leaves, with_value

EXAMPLE = Path(__file__).parents[2] / "examples" / "robots" / "my_claw.yaml"
FACTS = (
    "arm_joints",
    "gripper_joints",
    "tool_frame",
    "home_q",
    "gripper_open",
    "gripper_closed",
    "grasp_width_m",
    "arm_gains",
    "gripper_gains",
    "finger_links",
    "finger_friction",
    "approach_axis_tool",
    "closing_axis_tool",
    "width_per_gripper_unit_m",
    "fingertip_below_tool_m",
    "keyframes",
    "max_approach_tilt_deg",
    "fixed_jaw_face_m",
    "grip_depth_m",
    "carry_tilted",
    "match_yaw",
    "pick_timing",
)


def written(tmp_path: Path, change: dict, name: str = "arm.yaml") -> Path:
    """The example robot file with `change` applied (a value None removes the field), written under tmp_path."""
    data = yaml.safe_load(EXAMPLE.read_text())
    data["urdf"] = str((EXAMPLE.parent / data["urdf"]).resolve())
    for key, value in change.items():
        if value is None:
            data.pop(key, None)
        else:
            data[key] = value
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


def test_the_example_file_declares_the_openclaw_under_a_new_uid():
    spec = load_robot_file(EXAMPLE)
    builtin = get_robot("openclaw")
    assert spec.uid == "my_claw" and spec.declared_in == str(EXAMPLE.resolve())
    assert {f: getattr(spec, f) for f in FACTS} == {f: getattr(builtin, f) for f in FACTS}
    assert reach_m_of(spec) == reach_m_of(builtin)  # measured from the same kinematics
    assert spec.urdf_text() == builtin.urdf_text()


@pytest.mark.parametrize(
    "change, field, says",
    [
        ({"tool_fram": "tool_link"}, "tool_fram", "Extra inputs are not permitted"),
        ({"uid": None}, "uid", "Field required"),
        ({"uid": "My Arm"}, "uid", "should match pattern"),
        (
            {"arm_joints": ["shoulder_pan", "shoulder_lift", "elbw", "forearm_roll", "wrist_pitch", "wrist_roll"]},
            "arm_joints.2",
            "no movable joint 'elbw' in the URDF; did you mean elbow",
        ),
        ({"tool_frame": "tool"}, "tool_frame", "no frame 'tool' in the URDF; did you mean tool_link"),
        ({"finger_links": ["finger_left_link", "finger_rite_link"]}, "finger_links.1", "no link 'finger_rite_link'"),
        ({"home_q": [0.0, -0.2, 1.9]}, "home_q", "3 values for 6 joints"),
        ({"home_q": [0.0, -0.2, 9.0, 0.0, 1.44, 0.0]}, "home_q.2", "9 is beyond joint 'elbow''s limits"),
        ({"gripper_closed_q": [0.035, 0.035]}, "gripper_closed_q", "equal to gripper_open_q"),
        ({"gripper_open_q": [0.035, 0.5]}, "gripper_open_q.1", "beyond joint 'finger_right''s limits"),
        ({"grasp_width_m": [0.06, 0.02]}, "(top level)", "must be below the largest"),
        ({"approach_axis_tool": [0, 0, 2]}, "approach_axis_tool", "unit vector"),
        ({"home_q": [0.0, "nan", 1.9, 0.0, 1.44, 0.0]}, "home_q.1", "finite number"),
        ({"urdf": "nowhere/arm.urdf"}, "urdf", "no such file"),
        ({"keyframes": {"up": [0, 0]}}, "keyframes.up", "2 values for 6 joints"),
        ({"pick_timing": {"hover": 0.05}}, "pick_timing", "no timing field 'hover'; fields: hover_m"),
        ({"max_approach_tilt_deg": 90}, "max_approach_tilt_deg", "less than or equal to 80"),
        ({"reach_m": 0.62}, "reach_m", "the reach is measured from the arm's kinematics, not declared"),
        ({"urdf": "arm\x00.urdf"}, "urdf", "a file name cannot hold a NUL byte"),  # (hypothesis found it)
        ({"package_root": "\x00"}, "package_root", "a file name cannot hold a NUL byte"),
    ],
)
def test_each_kind_of_mistake_is_one_line_naming_the_file_and_field(tmp_path, change, field, says):
    path = written(tmp_path, change)
    with pytest.raises(RobotFileError) as info:
        load_robot_file(path)
    message = str(info.value)
    assert message.startswith(f"{path.resolve()}: {field}: ") and says in message and "\n" not in message, message


def test_files_that_are_not_robot_declarations_are_refused_in_one_line(tmp_path):
    (tmp_path / "binary.yaml").write_bytes(b"uid: x\n\xff\xfe")
    (tmp_path / "list.yaml").write_text("- 1\n- 2\n")
    (tmp_path / "broken.urdf").write_text("<robot name='x'><link name='a'></robot>")
    openclaw = (EXAMPLE.parent / yaml.safe_load(EXAMPLE.read_text())["urdf"]).resolve().read_text()
    (tmp_path / "no_mesh.urdf").write_text(
        openclaw.replace(
            "<collision>", '<collision><geometry><mesh filename="gone.stl"/></geometry></collision><collision>', 1
        )
    )
    cases = {
        tmp_path / "binary.yaml": "not UTF-8 text (byte 7",
        tmp_path / "list.yaml": "a robot file must hold a mapping of fields",
        tmp_path: "a directory, not a robot file",
        tmp_path / "missing.yaml": "no such file",
        written(
            tmp_path, {"urdf": str(tmp_path / "broken.urdf")}, "bad_urdf.yaml"
        ): "urdf: not a URDF Pinocchio can read",
        written(
            tmp_path, {"urdf": str(tmp_path / "no_mesh.urdf")}, "no_mesh.yaml"
        ): "names a mesh that is not there: gone.stl",
    }
    for path, says in cases.items():
        with pytest.raises(RobotFileError) as info:
            load_robot_file(path)
        assert says in str(info.value) and "\n" not in str(info.value), str(info.value)


def test_a_file_registers_once_and_its_uid_cannot_be_taken_twice(tmp_path):
    first = register_file(written(tmp_path, {"uid": "claw_twice"}, "a.yaml"))
    assert register_file(tmp_path / "a.yaml") is first and get_robot("claw_twice") is first
    with pytest.raises(RobotFileError, match=r"uid: 'claw_twice' is taken \(declared in .*a\.yaml\)"):
        register_file(written(tmp_path, {"uid": "claw_twice"}, "b.yaml"))
    with pytest.raises(RobotFileError, match="uid: 'openclaw' is taken"):
        register_file(written(tmp_path, {"uid": "openclaw"}, "c.yaml"))


@pytest.mark.parametrize("uid", ["panda", "so101"])
def test_an_arm_from_another_package_with_package_uris_loads_as_the_registered_one(tmp_path, uid):
    if not is_available(uid):
        pytest.skip("needs the models extra")
    spec = get_robot(uid)
    urdf = spec.urdf_path()
    facts = {f: getattr(spec, f) for f in FACTS}
    renamed = {"home_q": "home_q", "gripper_open": "gripper_open_q", "gripper_closed": "gripper_closed_q"}
    data = {
        renamed.get(f, f): (
            dataclasses.asdict(v) if dataclasses.is_dataclass(v) else list(v) if isinstance(v, tuple) else v
        )
        for f, v in facts.items()
        if v is not None
    }
    # its URDF names meshes as package://example-robot-data/robots/...: the packages lie in share/
    data.update(uid=f"my_{uid}", urdf=str(urdf), package_root=str(urdf.parents[4]))
    path = tmp_path / f"my_{uid}.yaml"
    path.write_text(yaml.safe_dump(data))
    declared = load_robot_file(path)
    assert declared.urdf_text() == spec.urdf_text()  # package:// URIs resolved to the same meshes
    assert {f: getattr(declared, f) for f in FACTS} == facts
    assert reach_m_of(declared) == reach_m_of(spec)


@settings(
    max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture]
)
@given(st.data(), WRONG)
def test_any_field_set_to_anything_gives_a_robot_or_one_line_naming_the_file(tmp_path, data, value):
    """Every value of the example file, and every field whole, set to anything: a declaration, or a
    `RobotFileError` of one line that names the file; never another exception."""
    example = yaml.safe_load(EXAMPLE.read_text())
    example["urdf"] = str((EXAMPLE.parent / example["urdf"]).resolve())
    path = data.draw(st.sampled_from([p for p in leaves(example) if p != ("urdf",)] + [(k,) for k in example]))
    file = tmp_path / "arm.yaml"
    file.write_text(yaml.safe_dump(with_value(example, path, value)))
    try:
        load_robot_file(file)
    except RobotFileError as exc:
        assert str(exc).startswith(f"{file.resolve()}: ") and "\n" not in str(exc), (path, value, str(exc))


@pytest.mark.parametrize("urdf", ["\n", "arm\n.urdf", "\t\x00"])
def test_a_file_name_with_control_characters_is_said_on_one_line(tmp_path, urdf):
    """What hypothesis found once: a URDF named "\\n" made a two-line error. Control characters are escaped."""
    example = yaml.safe_load(EXAMPLE.read_text()) | {"urdf": urdf}
    file = tmp_path / "arm.yaml"
    file.write_text(yaml.safe_dump(example))
    with pytest.raises(RobotFileError) as raised:
        load_robot_file(file)
    assert "\n" not in str(raised.value) and str(raised.value).startswith(f"{file.resolve()}: urdf: "), raised.value
