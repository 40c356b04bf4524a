"""The order the two workers take test files in: light files beside wall-time ones, lines beside lines."""

from tests.conftest import file_kind
from tests.file_pairing import ALONE, LIGHT, LINES, WALL, next_file

WAITING = {"a_light.py": LIGHT, "a_wall.py": WALL, "b_lines.py": LINES, "a_browser.py": ALONE, "b_light.py": LIGHT}


def test_beside_a_wall_time_file_a_worker_takes_a_light_one_and_beside_lines_it_takes_lines():
    assert next_file(WAITING, WALL) == "a_light.py"
    assert next_file(WAITING, LINES) == "a_browser.py"  # alone costs the same anywhere: early, while lines pair
    assert next_file({f: k for f, k in WAITING.items() if k != ALONE}, LINES) == "b_lines.py"
    assert next_file(WAITING, LIGHT) == "a_wall.py"
    assert next_file(WAITING, ALONE) == "b_lines.py"


def test_when_the_kind_wanted_is_gone_the_next_in_the_order_is_taken_and_nothing_left_is_none():
    assert next_file({"w.py": WALL, "l.py": LINES}, WALL) == "w.py"
    assert next_file({}, None) is None


def test_the_suites_files_are_told_apart_by_their_locks_and_marks():
    assert file_kind("tests/fleet/monitor/test_browser.py") == ALONE
    assert file_kind("tests/fleet/test_run.py") == WALL
    assert file_kind("tests/test_examples.py") == LINES  # marked slow
    assert file_kind("tests/fleet/cli/test_cli.py") == LINES  # heavy
    assert file_kind("tests/fleet/bus/test_codec.py") == LIGHT
