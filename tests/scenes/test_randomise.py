"""Domain randomisation in the scene file: ranges validated like every field, drawn once per run from its seed."""

from pathlib import Path

import pytest
import yaml

from scenes import load_scene
from scenes.loader import SceneError

QUICK_LINE = Path(__file__).parents[1] / "fleet" / "scenes_data" / "quick_line.yaml"
RANGES = {
    "part_friction": {"uniform": [0.5, 1.0]},
    "part_mass_scale": {"uniform": [0.8, 1.2]},
    "part_size_scale": {"normal": [1.0, 0.05]},
    "belt_speed_scale": {"uniform": [0.9, 1.1]},
    "arrival_rate_scale": {"uniform": [0.5, 1.5]},
    "arm_gain_scale": {"uniform": [0.9, 1.1]},
    "part_pose_noise_m": {"uniform": [0.0, 0.003]},
}


def randomised(tmp_path: Path, ranges: dict) -> Path:
    data = yaml.safe_load(QUICK_LINE.read_text()) | {"randomise": ranges}
    path = tmp_path / "randomised.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_a_seed_draws_one_set_of_values_within_the_ranges_and_applies_them(tmp_path):
    path = randomised(tmp_path, RANGES)
    plain = load_scene(QUICK_LINE)
    a, again, other = load_scene(path, seed=4), load_scene(path, seed=4), load_scene(path, seed=5)
    assert set(a.randomised) == set(RANGES) and a.randomised == again.randomised and a.randomised != other.randomised
    assert 0.5 <= a.randomised["part_friction"] <= 1.0 and 0.0 <= a.randomised["part_pose_noise_m"] <= 0.003
    assert all(p.friction == a.randomised["part_friction"] for f in a.feeders for p in f.parts)
    assert a.conveyor.speed_m_per_s == pytest.approx(plain.conveyor.speed_m_per_s * a.randomised["belt_speed_scale"])
    assert a.feeders[0].parts[0].mass_kg == pytest.approx(
        plain.feeders[0].parts[0].mass_kg * a.randomised["part_mass_scale"]
    )
    assert (
        a.drive_gain_scale == a.randomised["arm_gain_scale"]
        and a.part_pose_noise_m == a.randomised["part_pose_noise_m"]
    )
    assert a.randomise is None, "a drawn scene is concrete"
    assert plain.randomised == {}


@pytest.mark.parametrize(
    "ranges, field, words",
    [
        ({"part_friction": {"uniform": [1.0, 0.5]}}, "randomise.part_friction", "above high"),
        (
            {"belt_speed_scale": {"uniform": [0.9, 1.1], "normal": [1.0, 0.1]}},
            "randomise.belt_speed_scale",
            "exactly one",
        ),
        ({"part_mass_scale": {"normal": [1.0, -0.1]}}, "randomise.part_mass_scale", "negative"),
        ({"part_colour": {"uniform": [0, 1]}}, "randomise.part_colour", "Extra inputs"),
    ],
)
def test_a_bad_range_names_its_file_and_field(tmp_path, ranges, field, words):
    path = randomised(tmp_path, ranges)
    with pytest.raises(SceneError) as err:
        load_scene(path)
    assert str(path) in str(err.value) and field in str(err.value) and words in str(err.value)
