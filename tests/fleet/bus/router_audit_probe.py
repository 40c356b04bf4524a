"""Run as a process of its own (Zenoh's log is set up once per process): a router with a run's access control and
`RouterAudit`, a client logged in as arm_0 that says what it may and what it may not (by key, and through declared
publishers, which the router decides once, for its cache, and then per message from it), and the counts as JSON."""

import json
import sys
import time

import zenoh

from fleet.bus.bus_config import write_run_bus
from fleet.bus.router_audit import RouterAudit
from fleet.bus.session import free_loopback_port


def main(folder: str) -> None:
    bus = write_run_bus(f"{folder}/bus", ["arm_0", "arm_1"], free_loopback_port())
    audit = RouterAudit(f"{folder}/router.log")
    audit.start()
    with zenoh.open(zenoh.Config.from_file(bus.config_for("sim"))) as router:
        heard = []
        subs = [router.declare_subscriber(f"clawfleet/r/{k}", heard.append) for k in ("estop", "arm/*/goal")]
        with zenoh.open(zenoh.Config.from_file(bus.config_for("arm_0"))) as arm:
            time.sleep(0.5)
            declared = [arm.declare_publisher(f"clawfleet/r/arm/{a}/goal") for a in ("arm_1", "arm_0")]
            time.sleep(0.3)
            for _ in range(3):
                arm.put("clawfleet/r/arm/arm_1/goal", b"not mine")
                arm.put("clawfleet/r/estop", b"not my role")
                arm.put("clawfleet/r/arm/arm_0/goal", b"mine")
                for publisher in declared:
                    publisher.put(b"by a declared publisher")
            time.sleep(0.5)
        for sub in subs:
            sub.undeclare()
    print(json.dumps({"refused": audit.refused(), "heard": [str(s.key_expr) for s in heard]}))


if __name__ == "__main__":
    main(sys.argv[1])
