"""`fleet check` over scenes changed anywhere: any field of any bundled scene set to an extreme or wrong-typed value
gives "ok" (exit 0) or one line that names the file (exit 2), never a traceback."""

import contextlib
import io
import tempfile
from pathlib import Path

import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fleet.cli import main
from scenes import bundled_scene_names
from scenes.loader import BUNDLED_DIR
from tests.wrong_values import WRONG, leaves, with_value

SCENES = {name: yaml.safe_load((BUNDLED_DIR / f"{name}.yaml").read_text()) for name in bundled_scene_names()}


def check(data: object) -> tuple[int, str, str]:
    """`fleet check` on the data written as a scene file: exit status, stdout, stderr."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "changed_scene.yaml"
        path.write_text(yaml.dump(data, Dumper=yaml.CSafeDumper))  # libyaml: the pure-Python dumper took half the time
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main(["check", str(path)])
        return code, out.getvalue(), err.getvalue().replace(str(path), "FILE")


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data(), WRONG)
def test_any_field_set_to_anything_gives_ok_or_one_line_naming_the_file(data, value):
    name = data.draw(st.sampled_from(sorted(SCENES)))
    path = data.draw(st.sampled_from(leaves(SCENES[name])))
    code, out, err = check(with_value(SCENES[name], path, value))
    assert code in (0, 2), (path, value, err)
    if code == 2:
        assert err.startswith("fleet: error: FILE") and err.count("\n") == 1, (path, value, err)
    else:
        assert out.startswith("ok"), (path, value, out)


@settings(max_examples=40, deadline=None)
@given(st.sampled_from(sorted(SCENES)), st.sampled_from(["arms", "stations", "feeders", "conveyor", "cameras"]), WRONG)
def test_whole_sections_replaced_by_anything_give_one_line(name, section, value):
    code, _, err = check(with_value(SCENES[name], (section,), value))
    assert code in (0, 2) and (code == 0 or err.count("\n") == 1), (section, value, err)
