"""Hostile YAML in scene and robot files: alias bombs, deep nests, huge scalars and wide lists are judged quickly,
in one line naming the file, without the document ever being built; anchors within bounds still work."""

import time
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robots.robot_file import RobotFileError, load_robot_file
from scenes import SceneError, load_scene
from scenes.loader import BUNDLED_DIR, MAX_SCENE_BYTES
from scenes.yaml_file import MAX_DEPTH, MAX_VALUES

CPU_BUDGET_S = 1.0  # the bound for a file under 1 MB; measured 0.0-0.05 s on a 2-core machine


def alias_bomb(levels: int, fan_out: int) -> str:
    """`levels` anchors, each a list of `fan_out` aliases of the one before: a few hundred bytes, fan_out**levels
    values once expanded."""
    lines = ["name: bomb", "a0: &a0 [" + ", ".join(["x"] * fan_out) + "]"]
    lines += [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * fan_out) + "]" for i in range(1, levels)]
    return "\n".join(lines + [f"stations: *a{levels - 1}"]) + "\n"


def deep_flow(depth: int) -> str:
    return "name: deep\nstations: " + "[" * depth + "]" * depth + "\n"


def deep_block(depth: int) -> str:
    return "name: deep\n" + "".join("  " * i + f"k{i}:\n" for i in range(depth)) + "  " * depth + "x\n"


def huge_scalar(chars: int) -> str:
    return f'name: cell\ndescription: "{"x" * chars}"\n'


def wide_list(items: int) -> str:
    return "name: wide\nstations: [" + ", ".join(["1"] * items) + "]\n"


HOSTILE = st.one_of(
    st.builds(alias_bomb, st.integers(3, 12), st.integers(5, 12)),
    st.builds(deep_flow, st.integers(MAX_DEPTH, 5_000)),
    st.builds(deep_block, st.integers(MAX_DEPTH, 900)),
    st.builds(huge_scalar, st.integers(100_000, MAX_SCENE_BYTES - 100)),
    st.builds(wide_list, st.integers(MAX_VALUES, (MAX_SCENE_BYTES - 100) // 3)),
)


def judged(path: Path, load) -> tuple[Exception, float]:
    """The error `load` raises for `path`, and the CPU seconds it took to say so."""
    start = time.thread_time()
    with pytest.raises((SceneError, RobotFileError)) as caught:
        load(path)
    return caught.value, time.thread_time() - start


@pytest.mark.filterwarnings("ignore::hypothesis.errors.HypothesisWarning")  # a megabyte example's repr is long
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(text=HOSTILE, robot=st.booleans())
def test_any_hostile_file_under_a_megabyte_is_refused_in_one_line_within_a_second(tmp_path_factory, text, robot):
    path = tmp_path_factory.mktemp("hostile") / "hostile.yaml"
    path.write_text(text)
    assert path.stat().st_size < MAX_SCENE_BYTES
    error, cpu_s = judged(path, load_robot_file if robot else load_scene)
    message = str(error)
    assert message.startswith(str(path.resolve() if robot else path)) and "\n" not in message, message
    assert cpu_s < CPU_BUDGET_S, f"{cpu_s:.2f} CPU s to refuse it: {message}"


def test_an_alias_bomb_is_refused_naming_the_bound_and_the_line(tmp_path):
    path = tmp_path / "bomb.yaml"
    path.write_text(alias_bomb(9, 9))  # 9**9 = 387,420,489 values from 200-odd bytes
    with pytest.raises(SceneError) as caught:
        load_scene(path)
    bound = "more than 20,000 values with aliases expanded: a scene needs far fewer"
    assert str(caught.value) == f"{path}: line 6: {bound}"  # a4, 9**5 values, passes the bound


def test_a_recursive_alias_and_an_undefined_one_are_refused(tmp_path):
    path = tmp_path / "loop.yaml"
    path.write_text("name: loop\nstations: &s [1, *s]\n")
    with pytest.raises(SceneError, match=r"line 2: alias \*s refers to a value that holds it"):
        load_scene(path)
    path.write_text("name: loop\nstations: *nowhere\n")
    with pytest.raises(SceneError, match=r"line 2: alias \*nowhere names no anchor before it"):
        load_scene(path)


def test_anchors_within_bounds_still_declare_a_scene(tmp_path):
    text = (BUNDLED_DIR / "pick_cell.yaml").read_text()
    kinds = "images: [rgb, depth, segmentation]"
    assert text.count(kinds) == 2
    first = text.index(kinds)
    anchored = text[:first] + "images: &kinds [rgb, depth, segmentation]" + text[first + len(kinds) :]
    anchored = anchored.replace(kinds, "images: *kinds")
    path = tmp_path / "anchored.yaml"
    path.write_text(anchored)
    assert load_scene(path).cameras == load_scene("pick_cell").cameras
