"""An arm's reach, cell by cell: each answer is the cell's own, whichever cells were asked before, so a table kept on
disk by one process gives another the same answers without solving them."""

import numpy as np
import pytest

from coordinator.capacity import capacity_bound
from coordinator.reach_cache import GRID_M, CachedReach, cell_of, parent_cell
from coordinator.reach_cells import scene_cells
from coordinator.reach_table import read_table, save_reach, table_key, table_path
from robots.registry import get_robot, is_available
from scenes import load_scene


def along_the_belt(y: float = 0.0, z: float = 0.2) -> list[np.ndarray]:
    return [np.array([x, y, z]) for x in np.arange(0.40, 1.02, 0.02)]


def so101():
    if not is_available("so101"):
        pytest.skip("needs the models extra")
    return load_scene("mixed_fleet").arm("arm_1")  # a short arm that must lean: its full search is the costly one


def test_a_cell_is_first_solved_from_the_nearest_cell_at_its_height_of_the_next_coarser_lattice():
    assert parent_cell((5, -3, 21)) == (4, -4, 21)  # at its own height
    assert parent_cell((4, -4, 21)) == (0, 0, 21)
    assert parent_cell((0, -16, 21)) is None  # the coarsest lattice: searched in full
    assert parent_cell((6, 2, 18)) == (8, 4, 18)  # half way rounds up, on either side of zero alike
    assert parent_cell((-6, -2, 18)) == (-4, 0, 18)


def test_a_cells_answer_does_not_depend_on_which_cells_were_asked_before():
    arm = so101()
    spots = along_the_belt() + along_the_belt(0.05, 0.22)
    forward, backward = CachedReach.of(arm, shared=False), CachedReach.of(arm, shared=False)
    ahead = [forward.joints(p) for p in spots]
    behind = [backward.joints(p) for p in reversed(spots)][::-1]
    assert sum(q is not None for q in ahead) >= 10
    for a, b in zip(ahead, behind):
        assert (a is None) == (b is None) and (a is None or np.array_equal(a, b))


def test_cells_solved_from_their_parent_are_real_reaches_with_few_full_searches():
    arm, spec = so101(), get_robot("so101")
    cached = CachedReach.of(arm, shared=False)
    found_by_search = []
    search = cached.top_down.reach_pose
    cached.top_down.reach_pose = lambda spot: (lambda r: found_by_search.append(r is not None) or r)(search(spot))
    spots = along_the_belt()  # 62 cm of belt, a spot every 2 cm
    answers = [cached.joints(p) for p in spots]
    full = CachedReach.of(arm, shared=False).top_down
    cells = [np.round(p / GRID_M) * GRID_M for p in spots]
    assert [a is not None for a in answers] == [full.joints_for(c) is not None for c in cells]
    assert sum(a is not None for a in answers) >= 20
    assert sum(found_by_search) <= 5, "a reached cell is searched in full about once every 16 cm: the rest walk there"
    centre = np.asarray(spec.grasp_centre_tool(sum(spec.grasp_width_m) / 2))
    for c, q in zip(cells, answers):
        if q is not None:  # a real reach: the claw's grasp centre is at the spot
            tool = full.base_to_world @ full.km.frame_pose(full.km.full_q(q))
            assert np.linalg.norm(tool[:3, :3] @ centre + tool[:3, 3] - c) < 1e-3


def test_a_table_on_disk_gives_another_reach_the_same_answers_without_solving(tmp_path, monkeypatch):
    monkeypatch.setenv("CLAWFLEET_CACHE_DIR", str(tmp_path))
    arm = load_scene("sorting_line").arm("arm_1")
    spots = along_the_belt(0.0, 0.19)
    first = CachedReach.of(arm, shared=False)
    first.table_path = table_path("openclaw", table_key(first.top_down, (GRID_M, (16, 4, 1))))
    answers = [first.joints(p) for p in spots]
    within = [c for c in first.answers() if not first.top_down.beyond(np.array(c) * GRID_M)]  # past it: not kept
    assert save_reach([first]) == len(within) and not first.worked_out
    second = CachedReach(first.top_down, first.table_path)
    assert [second.joints(p) for p in spots] and second.worked_out == set() and second.search_s == 0.0
    for a, b in zip(answers, [second.joints(p) for p in spots]):
        assert (a is None) == (b is None) and (a is None or np.array_equal(a, b))
    assert sum(a is None for a in answers) >= 1 and sum(a is not None for a in answers) >= 10  # both kinds kept


def test_a_table_belongs_to_one_placement_and_a_broken_file_is_read_as_empty(tmp_path, monkeypatch):
    monkeypatch.setenv("CLAWFLEET_CACHE_DIR", str(tmp_path))
    scene = load_scene("sorting_line")
    a, b = (CachedReach.of(scene.arm(n), shared=False) for n in ("arm_0", "arm_1"))
    grid = (GRID_M, (16, 4, 1))
    assert table_key(a.top_down, grid) != table_key(b.top_down, grid)
    assert table_key(a.top_down, grid) == table_key(CachedReach.of(scene.arm("arm_0"), shared=False).top_down, grid)
    path = table_path("openclaw", table_key(a.top_down, grid))
    path.parent.mkdir(parents=True)
    path.write_bytes(b"not a table")
    assert read_table(path) == {}
    reach = CachedReach(a.top_down, path)
    reach.joints((0.0, -0.2, 0.2))
    assert save_reach([reach]) >= 1 and len(read_table(path)) >= 1  # written anew (the cell, its parents)


def test_tables_can_be_turned_off(monkeypatch):
    monkeypatch.setenv("CLAWFLEET_CACHE_DIR", "off")
    arm = load_scene("sorting_line").arm("arm_0")
    reach = CachedReach.of(arm, shared=False)
    assert table_path("openclaw", table_key(reach.top_down, (GRID_M, (16, 4, 1)))) is None


def test_the_cells_the_capacity_model_asks_are_among_those_fleet_reach_fills():
    scene = load_scene("mixed_infeed")  # belt parts and a tray of parts
    reach = {a.name: CachedReach.of(a, shared=False) for a in scene.arms}
    asked = {name: set() for name in reach}
    for name, r in reach.items():
        joints = r.joints
        r.joints = lambda point, name=name, joints=joints: asked[name].add(cell_of(point)) or joints(point)
    capacity_bound(scene, reach=reach)
    for arm in scene.arms:
        within = {c for c in asked[arm.name] if not reach[arm.name].top_down.beyond(np.array(c) * GRID_M)}
        assert within and within <= set(scene_cells(scene, arm)), sorted(within - set(scene_cells(scene, arm)))[:5]


def test_a_pickled_reach_keeps_what_it_worked_out_and_reads_its_table_again(tmp_path, monkeypatch):
    """A run's snapshot holds the coordinator's reach: not the whole table (thousands of cells after `fleet reach`),
    only what the run worked out; restored, it answers as before."""
    import pickle

    monkeypatch.setenv("CLAWFLEET_CACHE_DIR", str(tmp_path))
    arm = load_scene("sorting_line").arm("arm_1")
    first = CachedReach.of(arm, shared=False)
    first.table_path = table_path("openclaw", table_key(first.top_down, (GRID_M, (16, 4, 1))))
    spots = along_the_belt(0.0, 0.19)
    answers = [first.joints(p) for p in spots[:15]]
    save_reach([first])  # the table holds those
    answers += [first.joints(p) for p in spots[15:]]  # these only in memory
    restored = pickle.loads(pickle.dumps(first))
    assert set(restored.__getstate__()["_cache"]) == first.worked_out
    for a, b in zip(answers, [restored.joints(p) for p in spots]):
        assert (a is None) == (b is None) and (a is None or np.array_equal(a, b))
    assert restored.worked_out == first.worked_out, "nothing worked out again"
