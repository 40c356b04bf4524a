"""Offered load: feeders scaled so parts arrive at a multiple of what the arms can just complete, by the capacity
model; the scaled scene's bound is what the sweep asked for."""

import pytest

from coordinator.capacity import capacity_bound
from coordinator.offered_load import feeder_rates_for_load, saturating_scale
from fleet.common.scene_loading import load_checked_scene
from fleet.common.scene_overrides import scene_with
from scenes.loader import SceneError


@pytest.mark.parametrize("name", ["sorting_line", "mixed_infeed", "assembly_line"])
def test_load_one_is_the_rate_the_arms_just_complete(name, tmp_path):
    scene = load_checked_scene(name)
    scale = saturating_scale(scene)
    nominal = capacity_bound(scene).arrivals_per_min
    assert 0 < scale < 100
    at = {}
    for load in (0.5, 1.0, 1.25):
        scaled = capacity_bound(load_checked_scene(scene_with(name, {"load": load}, tmp_path)))
        at[load] = scaled
        assert scaled.arrivals_per_min == pytest.approx(load * scale * nominal, rel=1e-3)
    assert at[0.5].bottleneck == "arrivals" and at[1.0].throughput_bound_per_min == pytest.approx(
        at[1.0].arrivals_per_min, rel=2e-3
    )
    past = at[1.25]
    assert past.bottleneck != "arrivals", "past capacity the arms (or a station) limit the line"
    assert at[1.0].throughput_bound_per_min <= past.throughput_bound_per_min < past.arrivals_per_min, (
        "some parts must be missed; which, the allocator chooses (serving more of the quicker kinds can still add)"
    )


def test_a_load_the_feeders_cannot_give_is_one_line_naming_it(tmp_path):
    with pytest.raises(SceneError, match="load: load 500: feeder mixed would release"):
        scene_with("sorting_line", {"load": 500.0}, tmp_path)
    with pytest.raises(ValueError, match="give a positive multiple"):
        feeder_rates_for_load(load_checked_scene("sorting_line"), 0.0)
