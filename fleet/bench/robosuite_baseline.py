"""robosuite's TwoArmLift stepped with random actions: the baseline `fleet bench env --robosuite PYTHON` measures.

Run as a file by another interpreter, the one that has robosuite (it cannot share this environment: robosuite
1.5 pins `mink`, which wants numpy < 2, while Pinocchio's wheels need numpy >= 2), so it imports nothing of
clawfleet. Prints one JSON line: steps and agent-steps per second (two arms, each an agent), and the versions.
robosuite's defaults: two Pandas, the default composite controller, 20 Hz control over MuJoCo at 500 Hz,
no rendering, no camera observations. Exit 3 with one line on stderr if robosuite cannot be imported.
"""

import argparse
import json
import sys
import time


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=400, help="steps timed")
    parser.add_argument(
        "--warmup", type=int, default=50, help="steps before the clock starts (robosuite compiles with numba)"
    )
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    try:
        import numpy as np
        import robosuite
    except ImportError as exc:
        print(f"robosuite cannot be imported by {sys.executable}: {exc}", file=sys.stderr)
        return 3
    env = robosuite.make(
        "TwoArmLift",
        robots=["Panda", "Panda"],
        has_renderer=False,
        has_offscreen_renderer=False,
        use_camera_obs=False,
        control_freq=20,
    )
    env.reset()
    low, high = env.action_spec
    rng = np.random.default_rng(args.seed)
    actions = rng.uniform(low, high, (args.warmup + args.steps, len(low)))
    for action in actions[: args.warmup]:
        env.step(action)
    start = time.perf_counter()
    for action in actions[args.warmup :]:
        env.step(action)
    seconds = time.perf_counter() - start
    arms = 2
    import mujoco

    print(
        json.dumps(
            {
                "task": "TwoArmLift",
                "arms": arms,
                "steps": args.steps,
                "seconds": seconds,
                "steps_per_s": args.steps / seconds,
                "agent_steps_per_s": arms * args.steps / seconds,
                "robosuite": robosuite.__version__,
                "mujoco": mujoco.__version__,
            }
        )
    )
    env.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
