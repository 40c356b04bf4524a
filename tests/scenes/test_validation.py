"""Scene validation: every bundled scene passes; each kind of mistake names the file, the field and the reason."""

import copy
from pathlib import Path

import pytest
import yaml

from fleet.common.scene_loading import robot_facts
from scenes import SceneError, bundled_scene_names, load_scene
from scenes.loader import BUNDLED_DIR


@pytest.mark.parametrize("name", bundled_scene_names())
def test_bundled_scenes_are_valid(name):
    scene = load_scene(name, robots=robot_facts())
    assert scene.arms and all(a.name.startswith("arm_") for a in scene.arms)


@pytest.mark.parametrize("n", [1, 6, 12, 16, 24])
def test_sorting_line_takes_one_to_twenty_four_arms(n):
    scene = load_scene("sorting_line", arms=n, robots=robot_facts())
    assert [a.name for a in scene.arms] == [f"arm_{i}" for i in range(n)]
    assert len([s for s in scene.stations if s.kind == "bin"]) == n


@pytest.mark.parametrize("n", [1, 4, 12])
def test_up_to_twelve_arms_ride_the_belt_the_scene_declares(n):
    assert load_scene("sorting_line", arms=n).conveyor.length_m == 7.0


@pytest.mark.parametrize("n", [13, 24])
def test_a_longer_row_grows_the_belt_to_end_past_its_last_arm(n):
    scene = load_scene("sorting_line", arms=n)
    belt_end_x = scene.conveyor.pose.xyz[0] + scene.conveyor.length_m
    assert belt_end_x == pytest.approx(scene.arms[-1].base.xyz[0] + 0.35)


def test_sorting_line_refuses_twenty_five_arms():
    with pytest.raises(SceneError, match="arm_row.count"):
        load_scene("sorting_line", arms=25)


def test_a_row_too_long_for_any_belt_names_the_field(tmp_path):
    data = yaml.safe_load((BUNDLED_DIR / "sorting_line.yaml").read_text())
    data["arm_row"]["spacing_m"] = 1.0
    path = tmp_path / "long_row.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(SceneError, match=r"long_row.yaml.*arm_row.belt_past_last_m.*24 arms need a longer belt"):
        load_scene(str(path), arms=24)


def test_a_fixture_line_of_twenty_four_arms_is_eight_bays_each_with_its_own_infeed_fixture_and_routes():
    one, row = load_scene("assembly_line"), load_scene("assembly_line", arms=24, robots=robot_facts())
    assert [a.name for a in row.arms] == [f"arm_{i}" for i in range(24)]
    assert row.arms[:3] == one.arms and row.stations[:5] == one.stations and row.feeders[:2] == one.feeders
    assert row.arms[3].base.xyz == pytest.approx((one.arms[0].base.xyz[0] + 1.6, *one.arms[0].base.xyz[1:]))
    fixtures = [s for s in row.stations if s.kind == "fixture"]
    assert [s.name for s in fixtures] == ["fixture_0"] + [f"fixture_0_b{k}" for k in range(1, 8)]
    assert fixtures[7].assembles == ["bases_b7", "tops_b7"]
    bases = [f for f in row.feeders if f.name.startswith("bases")]
    assert [f.route for f in bases[1:3]] == [["fixture_0_b1", "output_tray_b1"], ["fixture_0_b2", "output_tray_b2"]]
    assert [row.drop_along_m(f) for f in bases] == pytest.approx([0.06 + 1.6 * k for k in range(8)])
    assert row.feeder("tops_b5").into == "tops_bin_b5"
    assert row.conveyor.length_m == pytest.approx(one.conveyor.length_m + 7 * 1.6)
    assert load_scene("assembly_line", arms=3) == one


def test_a_bay_to_repeat_names_its_arms_in_order(tmp_path):
    path = broken(tmp_path, set_(["arms", 2, "name"], "arm_9"))
    assert [a.name for a in load_scene(path).arms] == ["arm_0", "arm_1", "arm_9"]  # one bay: as declared
    with pytest.raises(SceneError, match=r"broken.yaml: bay_row: a repeated bay names its arms arm_0 .. arm_2"):
        load_scene(path, arms=6)


@pytest.mark.parametrize("arms, says", [(4, "takes bays of 3 arms"), (27, "takes 3 to 24, 3 a bay")])
def test_a_row_of_bays_takes_whole_bays_only(arms, says):
    with pytest.raises(SceneError, match=f"bay_row.count: {arms} arms asked for; this scene {says}"):
        load_scene("assembly_line", arms=arms)


def test_a_row_that_runs_off_the_floor_plan_names_its_first_arm(tmp_path):
    data = yaml.safe_load((BUNDLED_DIR / "sorting_line.yaml").read_text())
    data["arm_row"]["first_xyz"] = [99.0, -0.35, 0.0]  # found by hypothesis: the row's arms past 100 m raised
    path = tmp_path / "far_row.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(SceneError, match=r"far_row.yaml: arm_row.first_xyz: 4 arms: .*within 100 m of the origin"):
        load_scene(str(path))


def broken(tmp_path: Path, edit) -> Path:
    data = yaml.safe_load((BUNDLED_DIR / "assembly_line.yaml").read_text())
    edit(data)
    path = tmp_path / "broken.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def set_(keys, value):
    def edit(d):
        for k in keys[:-1]:
            d = d[k]
        d[keys[-1]] = value

    return edit


CASES = [
    ("unknown field", lambda d: d.update(conveyer={}), "conveyer", "Extra inputs"),
    ("missing field", lambda d: d["conveyor"].pop("length_m"), "conveyor.length_m", "Field required"),
    ("out of range", set_(["physics_hz"], 5), "physics_hz", "greater than or equal"),
    (
        "no solver iterations",
        set_(["solver_position_iterations"], 0),
        "solver_position_iterations",
        "greater than or equal",
    ),
    ("negative speed", set_(["conveyor", "speed_m_per_s"], -1), "conveyor.speed_m_per_s", "greater than or equal"),
    ("unknown model", set_(["arms", 1, "model"], "ur99"), "arms.1.model", "valid models: openclaw"),
    ("bases overlap", set_(["arms", 1, "base", "xyz"], [-0.25, -0.35, 0.0]), "arms.1.base.xyz", "bases need"),
    (
        "station unreachable",
        set_(["stations", 2, "pose", "xyz"], [3.0, 3.0, 0.0]),
        "stations.2.pose",
        "out of every arm's reach",
    ),
    (
        "conveyor unreachable",
        set_(["conveyor", "pose", "xyz"], [-1.0, 3.0, 0.08]),
        "conveyor.pose",
        "no stretch of the conveyor",
    ),
    ("duplicate arm", set_(["arms", 1, "name"], "arm_0"), "arms.1.name", "duplicate"),
    ("feeder into nothing", set_(["feeders", 1, "into"], "nowhere"), "feeders.1.into", "no station"),
    ("infeed past the belt", set_(["feeders", 0, "along_m"], 1.3), "feeders.0.along_m", "past the belt's end"),
    # found by hypothesis (tests/fleet/cli/test_check_properties.py): the capacity check's reach cache overflowed
    ("a station too tall", set_(["stations", 0, "size_m"], [0.1, 0.1, 1.8e306]), "stations.0.size_m", "and 3 m"),
    ("a base far off", set_(["arms", 0, "base", "xyz"], [1e300, 0.0, 0.0]), "arms.0.base.xyz", "within 100 m"),
    ("a bin fed along a belt", set_(["feeders", 1, "along_m"], 0.5), "feeders.1.along_m", "only a conveyor feeder"),
    ("control not dividing physics", set_(["control_hz"], 150), "(top level)", "whole multiple"),
    ("loss of one or more", set_(["network"], {"loss": 1.0}), "network.loss", "less than 1"),
    (
        "negative latency on a link",
        set_(["network"], {"links": {"arm_0": {"latency_ms": -1}}}),
        "network.links.arm_0.latency_ms",
        "greater than or equal",
    ),
    (
        "a link to nobody",
        set_(["network"], {"links": {"arm_9": {"loss": 0.1}}}),
        "network.links.arm_9",
        "links: arm_0, arm_1, arm_2, coordinator",
    ),
]


@pytest.mark.parametrize("label, edit, field, reason", CASES, ids=[c[0] for c in CASES])
def test_errors_name_file_field_and_reason(tmp_path, label, edit, field, reason):
    path = broken(tmp_path, edit)
    with pytest.raises(SceneError) as info:
        load_scene(path, robots=robot_facts())
    message = str(info.value)
    assert message.startswith(str(path))
    assert info.value.field == field, message
    assert reason in message
    assert "\n" not in message


def test_yaml_syntax_error_names_the_line(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("name: x\narms: [\n")
    with pytest.raises(SceneError, match="line"):
        load_scene(path)


def test_unknown_scene_name_lists_bundled_ones():
    with pytest.raises(SceneError, match="assembly_line"):
        load_scene("no_such_scene")


def numeric_leaves(node, path=()):
    """Every number in a scene file's data, by its path (lists by index)."""
    if isinstance(node, dict):
        for k, v in node.items():
            yield from numeric_leaves(v, (*path, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from numeric_leaves(v, (*path, i))
    elif isinstance(node, (int, float)) and not isinstance(node, bool):
        yield path


@pytest.mark.parametrize("name", bundled_scene_names())
@pytest.mark.parametrize("value", [float("nan"), float("inf"), float("-inf")])
def test_every_number_of_every_bundled_scene_refuses_a_non_finite_value_naming_file_and_field(tmp_path, name, value):
    """NaN and infinite numbers were accepted in places (arm bases, heights) and crashed or hung `fleet run` later:
    each number of each bundled scene, set to one, is refused by `load_scene` with the file and its field."""
    data = yaml.load((BUNDLED_DIR / f"{name}.yaml").read_text(), Loader=yaml.CSafeLoader)  # libyaml: 20x faster
    leaves = list(numeric_leaves(data))
    assert len(leaves) >= 10
    path = tmp_path / f"{name}.yaml"
    for leaf in leaves:
        edited = copy.deepcopy(data)
        node = edited
        for key in leaf[:-1]:
            node = node[key]
        node[leaf[-1]] = value
        path.write_text(yaml.dump(edited, Dumper=yaml.CSafeDumper))
        with pytest.raises(SceneError) as refused:
            load_scene(path, robots=robot_facts())
        message = str(refused.value)
        assert str(path) in message and "\n" not in message, message
