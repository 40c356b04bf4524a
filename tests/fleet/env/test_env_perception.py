"""The env's allocate mode through the cameras (`perception="cameras"`): its skills and dispatcher see the parts the
overhead camera shows, a frame late, near where they are but never their true poses; the same seed and actions
repeat exactly; a mode without parts to see refuses it."""

import numpy as np
import pytest

from fleet.env import parallel_env

pytestmark = pytest.mark.slow  # each steps a cell with its camera rendering

STEPS = 120  # 6 s of sim time at 20 decisions a second


def run(perception: str, seed: int = 1):
    env = parallel_env(scene="pick_cell", scenario="line", action_mode="allocate", perception=perception)
    env.reset(seed=seed)
    trace, gaps = [], []
    for _ in range(STEPS):
        seen = env.chooser.parts()
        truth = {p.part_id: p.position for p in env.world.active_parts()}
        gaps += [np.linalg.norm(view.position - truth[pid]) for pid, view in seen.items() if pid in truth]
        trace.append(sorted((pid, tuple(np.round(v.position, 9))) for pid, v in seen.items()))
        _, rewards, _, _, infos = env.step({a: first_choice(env.action_mask(a)) for a in env.agents})
        trace.append((rewards, {a: i["success"] for a, i in infos.items()}))
    return env, trace, gaps


def first_choice(mask: np.ndarray) -> int:
    """The first valid choice (1-4), else wait (0)."""
    valid = np.flatnonzero(mask[1:])
    return int(valid[0]) + 1 if len(valid) else 0


def test_the_cells_parts_are_those_the_camera_shows_and_the_same_seed_repeats_exactly():
    env, trace, gaps = run("cameras")
    _, again, _ = run("cameras")
    assert trace == again, "the same seed and actions: the same parts seen and the same rewards, step by step"
    assert len(gaps) > 20 and 0 < float(np.median(gaps)) < 0.01, "near the true parts (a frame late), never them"
    assert env.scenario.book.completed >= 1 and len(env.sight.frames) > 0
    _, truth_trace, truth_gaps = run("truth")
    assert max(truth_gaps) == 0.0 and truth_trace != trace, "on the truth the parts are the world's own"


def test_perception_needs_the_allocate_mode_and_one_of_two_sources():
    with pytest.raises(ValueError, match="perception='cameras' applies to action_mode 'allocate'"):
        parallel_env(scene="pick_cell", scenario="reach", perception="cameras")
    with pytest.raises(ValueError, match="valid: truth, cameras"):
        parallel_env(scene="pick_cell", scenario="line", action_mode="allocate", perception="lidar")
