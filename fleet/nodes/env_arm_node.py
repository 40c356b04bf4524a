"""One arm's process for the PettingZoo env's `distributed=True`: policy actions in, joint targets out.

The env publishes each step's action for this arm (`EnvAction`); this process turns
it into joint targets with the arm's own `robots.policy_actions.ActionTranslator`
(the same code the in-process env runs, so both paths give the same targets) and
answers with `EnvTargets`. Malformed requests are dropped and counted.

    python -m fleet.nodes.env_arm_node --scene sorting_line --arms 2 --arm arm_0 --action-mode ee_delta \\
        --run env_1 --connect tcp/127.0.0.1:7447
"""

from __future__ import annotations

import argparse
import sys

from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.keys import Keys
from fleet.bus.messages import EnvAction, EnvTargets
from fleet.bus.session import BusEndpoints, Inbox, add_bus_arguments, open_session
from fleet.common.processes import add_scene_arguments, node_arguments, write_node_report
from robots.frames import yaw_transform
from robots.policy_actions import CONTINUOUS_MODES, ActionTranslator
from robots.registry import get_robot


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="fleet-env-arm", description=__doc__.splitlines()[0])
    add_scene_arguments(parser)
    parser.add_argument("--arm", required=True, help="the arm id this process answers for")
    parser.add_argument("--action-mode", choices=CONTINUOUS_MODES, required=True)
    parser.add_argument("--report", help="write this process's figures (requests answered, dropped) to this JSON file")
    add_bus_arguments(parser)
    opened = node_arguments(parser, argv, "fleet-env-arm")
    if opened is None:
        return 2
    args, stop, scene = opened
    try:
        decl = scene.arm(args.arm)
    except KeyError as exc:
        print(f"fleet-env-arm: {exc.args[0]}", file=sys.stderr)
        return 2
    translator = ActionTranslator(
        get_robot(decl.model), yaw_transform(decl.base.xyz, decl.base.yaw_rad), args.action_mode
    )
    keys, drops, answered = Keys(args.run), DropCounter(), 0
    decoder = Decoder(EnvAction, drops)
    with open_session(BusEndpoints.from_args(args)) as session:
        inbox = Inbox()
        sub = session.declare_subscriber(keys.env_action(args.arm), inbox)
        pub = session.declare_publisher(keys.env_targets(args.arm))
        try:
            while not stop.should_stop():
                inbox.wait(0.1)
                for key, payload in inbox.drain():
                    msg = decoder.decode(key, payload)
                    if msg is None:
                        continue
                    if msg.arm != args.arm or msg.kind not in ("act", "reset"):
                        drops.drop(key, f"request for {msg.arm!r} of kind {msg.kind!r}")
                        continue
                    try:
                        if msg.kind == "reset":
                            translator.reset(msg.values)
                            q, opening = translator.q_target, translator.opening
                        else:
                            q, opening = translator.apply(msg.values)
                    except ValueError as exc:  # wrong action size: refused, counted, never a crash
                        drops.drop(key, str(exc))
                        continue
                    # this arm: row 0
                    pub.put(encode(EnvTargets(args.arm, msg.seq, tuple(q[0].tolist()), float(opening[0]))))
                    answered += 1
        finally:
            sub.undeclare()
            pub.undeclare()
            write_node_report(
                args.report,
                {"arm": args.arm, "answered": answered, "dropped_messages": drops.total, "stopped_by": stop.reason},
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
