"""`distributed=True`: each agent's action goes over Zenoh to its arm's own process, which answers with joint targets.

The env starts one `fleet.nodes.env_arm_node` process per arm on a loopback Zenoh
session of its own, sends every step's actions at once and waits for every arm's
answer (a step time-out names the arms that did not answer and their last log
line). `close()` stops the processes and frees the port; they also die with the env's
process (the nodes' parent-death signal).
"""

from __future__ import annotations

import itertools
import os
import shutil
import sys
import tempfile
import time
import weakref
from pathlib import Path

import numpy as np

from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.keys import Keys
from fleet.bus.messages import EnvAction, EnvTargets
from fleet.bus.session import BusEndpoints, Inbox, open_listening_session
from fleet.common.processes import ChildProcess, stop_children
from robots.policy_actions import CONTINUOUS_MODES, JointTargets

START_TIMEOUT_S = 60.0
STEP_TIMEOUT_S = 10.0
RESEND_EVERY_S = 0.25  # a reset is sent again until answered: subscribers may not be matched yet
_runs = itertools.count(1)


class RemoteArmsError(RuntimeError):
    """An arm's process did not answer; the message names it."""


def _stop(procs: list[ChildProcess], session, logs: Path) -> None:
    stop_children(procs, grace_s=5.0)
    try:
        session.close()
    except Exception:  # already closed
        pass
    shutil.rmtree(logs, ignore_errors=True)  # the processes' logs (an error quoted their last line already)


class RemoteActuators:
    """The arms' processes for one env; `translate(actions)` is one round trip over the bus."""

    def __init__(self, scene: str, n_arms: int | None, arms: list[str], action_mode: str) -> None:
        if action_mode not in CONTINUOUS_MODES:
            raise ValueError(
                f"distributed=True carries continuous actions ({', '.join(CONTINUOUS_MODES)}) to the arms' processes; "
                f"in action_mode {action_mode!r} the skills run in process: use distributed=False"
            )
        self.arms = arms
        self.keys = Keys(f"env_{os.getpid()}_{next(_runs)}")
        self.session, self.endpoint = open_listening_session(BusEndpoints())
        self.drops = DropCounter()
        self._decoder = Decoder(EnvTargets, self.drops)
        self._inbox = Inbox()
        self._sub = self.session.declare_subscriber(self.keys.all_arms("env_targets"), self._inbox)
        self._pubs = {a: self.session.declare_publisher(self.keys.env_action(a)) for a in arms}
        self._logs = Path(tempfile.mkdtemp(prefix="clawfleet_env_"))
        self.procs: dict[str, ChildProcess] = {}
        for arm in arms:
            argv = [
                sys.executable,
                "-m",
                "fleet.nodes.env_arm_node",
                "--scene",
                scene,
                "--run",
                self.keys.run,
                "--arm",
                arm,
                "--action-mode",
                action_mode,
                "--connect",
                self.endpoint,
            ]
            if n_arms is not None:
                argv += ["--arms", str(n_arms)]
            self.procs[arm] = ChildProcess(argv, self._logs / f"{arm}.log").start()
        self._finalizer = weakref.finalize(self, _stop, list(self.procs.values()), self.session, self._logs)
        self.seq = 0

    def reset(self, q_by_arm: dict[str, np.ndarray]) -> None:
        """Every arm's process starts from these joints (waits for all processes on the first call)."""
        self._round({a: ("reset", q) for a, q in q_by_arm.items()}, START_TIMEOUT_S, resend=True)

    def translate(self, actions: dict[str, np.ndarray]) -> dict[str, JointTargets]:
        """Send each arm its action; return every arm's joint targets."""
        answers = self._round({a: ("act", v) for a, v in actions.items()}, STEP_TIMEOUT_S, resend=False)
        return {a: JointTargets(np.asarray(m.q, float), m.gripper_opening) for a, m in answers.items()}

    def _round(
        self, requests: dict[str, tuple[str, np.ndarray]], timeout_s: float, resend: bool
    ) -> dict[str, EnvTargets]:
        self.seq += 1
        seq, answers = self.seq, {}
        deadline, sent_at = time.monotonic() + timeout_s, -1e9
        while len(answers) < len(requests):
            now = time.monotonic()
            missing = sorted(set(requests) - set(answers))
            if now > deadline or any(self.procs[a].poll() is not None for a in missing):  # a dead process never answers
                raise RemoteArmsError(self._silence_report(missing, timeout_s))
            if now - sent_at > (RESEND_EVERY_S if resend else 1e9):
                for arm, (kind, values) in requests.items():
                    if arm not in answers:
                        self._pubs[arm].put(
                            encode(EnvAction(arm, seq, kind, tuple(float(v) for v in np.ravel(values))))
                        )
                sent_at = now
            self._inbox.wait(0.05)
            for key, payload in self._inbox.drain():
                msg = self._decoder.decode(key, payload)
                if msg is not None and msg.seq == seq and msg.arm in requests:
                    answers[msg.arm] = msg
        return answers

    def _silence_report(self, arms: list[str], timeout_s: float) -> str:
        parts = []
        for arm in arms:
            proc = self.procs[arm]
            state = "running" if proc.poll() is None else f"exited with {proc.poll()}"
            last = proc.log_tail(1)
            parts.append(f"{arm} ({state}{': ' + last if last else ''})")
        return f"no answer within {timeout_s:g} s from the process of {', '.join(parts)}"

    def close(self) -> None:
        """Stop every arm's process and close the session (idempotent)."""
        if not self._finalizer.alive:
            return
        self._sub.undeclare()
        for pub in self._pubs.values():
            pub.undeclare()
        self._finalizer()
