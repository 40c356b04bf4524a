"""The line's capacity bound: the arrival rate when the line can take every part, else what its busiest arm or
station allows; hops no arm can serve are named and their parts left out."""

import pytest

from coordinator.capacity import capacity_bound
from scenes import load_scene
from scenes.loader import resolve_scene_path


def with_feeders(scene, **changes):
    feeders = [f.model_copy(update=changes) for f in scene.feeders]
    return scene.model_copy(update={"feeders": feeders})


def test_the_assembly_line_can_take_what_arrives_and_its_fixture_is_the_busiest_place():
    bound = capacity_bound(load_scene("assembly_line"))
    assert bound.arrivals_per_min == pytest.approx(6.0) and bound.throughput_bound_per_min == pytest.approx(6.0)
    assert bound.bottleneck == "arrivals"
    assert max(bound.station_busy, key=bound.station_busy.get) == "fixture_0"
    assert 0 < bound.station_busy["fixture_0"] < 1 and all(0 <= v <= 1 + 1e-9 for v in bound.arm_busy.values())


def test_a_flood_of_parts_is_capped_by_the_busiest_arm_or_station():
    scene = load_scene("sorting_line", arms=2)
    arrival = scene.feeders[0].arrival.model_copy(update={"rate_per_min": 200.0})
    bound = capacity_bound(with_feeders(scene, arrival=arrival))
    assert bound.arrivals_per_min == pytest.approx(200.0)
    assert 0 < bound.throughput_bound_per_min < 200.0
    assert bound.bottleneck != "arrivals" and bound.bottleneck_busy_fraction == pytest.approx(1.0, abs=1e-6)
    calm = capacity_bound(scene)
    assert calm.throughput_bound_per_min <= bound.throughput_bound_per_min, "more arrivals never lower the bound"


def test_a_station_out_of_every_arms_reach_is_named_and_its_parts_are_left_out():
    scene = load_scene("pick_cell")
    far = [s.model_copy(update={"pose": s.pose.model_copy(update={"xyz": (5.0, 5.0, 0.0)})}) for s in scene.stations]
    bound = capacity_bound(scene.model_copy(update={"stations": far}))
    assert bound.unservable and bound.throughput_bound_per_min == pytest.approx(0.0)


def test_hop_times_a_run_measured_replace_the_models_and_slower_arms_lower_the_bound():
    from coordinator.capacity import measured_hop_seconds
    from coordinator.tasks import Task, TaskState

    scene = load_scene("assembly_line")
    done = []
    for k, (arm, source, target, seconds) in enumerate(
        [
            ("arm_1", "tops_bin", "fixture_0", 12.0),
            ("arm_1", "tops_bin", "fixture_0", 14.0),
            ("arm_0", "conveyor", "fixture_0", 7.0),
        ]
    ):
        task = Task(k, k, source, target, 0.0, state=TaskState.DONE, arm=arm, assigned_s=10.0 * k)
        task.done_s = 10.0 * k + seconds
        done.append(task)
    done.append(Task(9, 9, "fixture_0", "output_tray", 0.0, state=TaskState.FAILED, arm="arm_2", assigned_s=1.0))
    measured = measured_hop_seconds(done)
    assert measured == {("arm_1", "tops_bin", "fixture_0"): 13.0, ("arm_0", "conveyor", "fixture_0"): 7.0}
    model, slow = capacity_bound(scene), capacity_bound(scene, measured)
    assert slow.throughput_bound_per_min < model.throughput_bound_per_min
    assert slow.bottleneck == "fixture_0" and slow.bottleneck_busy_fraction == pytest.approx(1.0)


def test_a_sorted_part_may_go_to_any_bin_of_its_colour_and_the_work_is_spread():
    """Six arms, three colours: each colour has two bins, and the bound counts both (the coordinator sends a part to
    whichever its arm reaches); of the ways to reach the bound, the one that loads the busiest arm least is reported."""
    bound = capacity_bound(load_scene("sorting_line", arms=6))
    assert bound.bottleneck == "arrivals" and not bound.unservable
    busy = list(bound.arm_busy.values())
    assert min(busy) > 0.0, bound.arm_busy  # arms 3-5 read 0% when only the first bin of a colour counted
    assert max(busy) - min(busy) < 0.02, bound.arm_busy


def test_a_runs_own_arrivals_bound_it_and_a_part_too_late_to_finish_does_not_count():
    """pick_cell's one arm can take every part that comes: the bound of a run is its own finishable arrivals. Of
    three parts seen over 60 s, the one that arrived a second before the end cannot be finished and is left out."""
    from coordinator.capacity import finishable_arrivals, least_route_seconds

    scene = load_scene("pick_cell")
    nominal = capacity_bound(scene)
    feeder = scene.feeders[0].name
    least = least_route_seconds(scene, nominal.model)
    assert all(0 < s < 30 for s in least.values()), least
    arrived = [(feeder, 0, 5.0), (feeder, 0, 20.0), (feeder, 0, 59.0)]
    counts = finishable_arrivals(scene, arrived, 60.0, nominal.model)
    assert sum(counts.values()) == 2
    run = capacity_bound(scene, model=nominal.model, arrivals_per_s={k: n / 60.0 for k, n in counts.items()})
    assert run.throughput_bound_per_min == pytest.approx(2.0) and run.bottleneck == "arrivals"
    none = capacity_bound(scene, model=nominal.model, arrivals_per_s={})
    assert none.throughput_bound_per_min == pytest.approx(0.0)


def test_a_run_with_more_bases_than_tops_is_limited_by_its_fixtures_pairing():
    """Eight bases and six tops in 120 s: an assembly needs one of each, so six pairs (12 parts) at best, and what
    limits is the fixture waiting for tops, not a busy arm or station."""
    scene = load_scene("assembly_line")
    nominal = capacity_bound(scene)
    run = capacity_bound(scene, model=nominal.model, arrivals_per_s={("bases", 0): 8 / 120, ("tops", 0): 6 / 120})
    assert run.throughput_bound_per_min == pytest.approx(6.0)
    assert run.bottleneck == "fixture_0 pairing" and run.bottleneck_busy_fraction < 1.0


def test_tops_without_bases_finish_nothing():
    """Nine tops and five bases: a top is only finished on a base, so five pairs (10 parts) at best, not 14."""
    scene = load_scene("assembly_line")
    nominal = capacity_bound(scene)
    run = capacity_bound(scene, model=nominal.model, arrivals_per_s={("bases", 0): 5 / 300, ("tops", 0): 9 / 300})
    assert run.throughput_bound_per_min == pytest.approx(10 * 60 / 300)
    assert run.bottleneck == "fixture_0 pairing"


def test_one_arm_alone_on_its_belt_cannot_take_a_burst_faster_than_it_works():
    """pick_cell's one arm has each part in reach for a few seconds and is busy a few seconds with each: four parts
    half a second apart cannot all be taken, the same four five seconds apart can; the run's bound says which."""
    from coordinator.capacity import belt_window_caps

    scene = load_scene("pick_cell")
    model = capacity_bound(scene).model
    window_s, busy_s = float(model.window_s[0, 0, 1] - model.window_s[0, 0, 0]), float(model.seconds[0].min())
    assert busy_s < window_s < 3 * busy_s, (window_s, busy_s)  # the premise: three parts do not fit in one window
    burst = [("trial_parts", k, 10.0 + 0.5 * k) for k in range(4)]
    spread = [("trial_parts", k, 10.0 + 5.0 * k) for k in range(4)]
    [cap] = belt_window_caps(scene, burst, 120.0, model)
    assert cap.arm == "arm_0" and cap.arrived == 4 and 1 < cap.at_most < 4
    assert belt_window_caps(scene, spread, 120.0, model)[0].at_most == 4
    assert belt_window_caps(scene, burst, 10.0 + window_s, model)[0].at_most < cap.at_most, (
        "the run's end cuts the last off"
    )
    run = capacity_bound(
        scene,
        model=model,
        arrivals_per_s={("trial_parts", k): 1 / 120.0 for k in range(4)},
        type_limits=[("arm_0 belt window", cap.types, cap.at_most / 120.0)],
    )
    assert run.throughput_bound_per_min == pytest.approx(cap.at_most / 2.0) and run.bottleneck == "arm_0 belt window"


def test_a_part_type_two_arms_can_take_gets_no_window_cap():
    from coordinator.capacity import belt_window_caps

    scene = load_scene("sorting_line", arms=4)
    model = capacity_bound(scene).model
    caps = belt_window_caps(scene, [("mixed", t, 5.0) for t in range(3)], 60.0, model)
    shared = {k for c in caps for k in c.types}
    assert ("mixed", 1) not in shared, caps  # arms 1 and 2 both take colour 1 into their own bins


def test_an_arm_that_can_serve_no_hop_is_named(tmp_path):
    """overlap_row with arm_1's blue bin moved into the blind spot behind its base: `fleet check` used to say only
    "ok", and the run then left arm_1 idle all along."""
    text = resolve_scene_path("overlap_row").read_text()
    path = tmp_path / "row.yaml"
    path.write_text(text.replace("xyz: [0.28, -0.2, 0.0]", "xyz: [0.0, -0.25, 0.0]"))
    assert capacity_bound(load_scene(str(path))).idle_arms == ["arm_1"]
    assert capacity_bound(load_scene("overlap_row")).idle_arms == []
