"""`fleet twin mirror`'s refusals: each in one line, before anything waits on the line, naming what was wrong (run
outside LeRobot's Python, a robot type LeRobot does not know, a setting its config does not take, a value it cannot
parse, a setting without a value)."""

import json
import subprocess
import sys
from pathlib import Path

DEAD = ["--connect", "tcp/127.0.0.1:1", "--wait", "1"]  # never reached: the robot is judged first


def mirror(python: Path | str, *args: str) -> subprocess.CompletedProcess:
    argv = [str(python), "-m", "fleet", "twin", "mirror", "--arm", "arm_1", *args, *DEAD]
    return subprocess.run(argv, capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL)


def one_line(done: subprocess.CompletedProcess) -> str:
    assert done.returncode == 2, done.stderr
    (line,) = done.stderr.strip().splitlines()
    return line


def test_outside_lerobots_python_it_says_which_python_to_run():
    said = one_line(mirror(sys.executable, "--robot-type", "so101_follower"))
    assert "run it with LeRobot's Python" in said and "install-lerobot" in said


REFUSED = [
    (["--robot-type", "so101"], "robot type 'so101': LeRobot knows "),
    (["--robot-type", "so101_follower", "--robot", "prot=/dev/ttyACM0"], "robot setting 'prot': a so101_follower"),
    (["--robot-type", "so101_follower", "--robot", "max_relative_target=far"], "`max_relative_target`"),
    (["--robot-type", "so101_follower", "--robot", "port"], "--robot 'port': give KEY=VALUE"),
]
# each refusal through the CLI's own entry point, in one of LeRobot's Pythons (its imports take seconds a start)
IN_ONE_PROCESS = """
import contextlib, io, json, sys
from fleet.cli import main
for argv in json.loads(sys.argv[1]):
    said = io.StringIO()
    with contextlib.redirect_stderr(said):
        try:
            rc = main(argv)
        except SystemExit as exc:
            rc = exc.code
    print(json.dumps([rc, said.getvalue()]))
"""


def test_a_robot_lerobot_cannot_make_is_refused_naming_why(lerobot):
    argvs = [["twin", "mirror", "--arm", "arm_1", *args, *DEAD] for args, _ in REFUSED]
    done = subprocess.run(
        [str(lerobot), "-c", IN_ONE_PROCESS, json.dumps(argvs)], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    answers = [json.loads(line) for line in done.stdout.splitlines()]
    for (rc, said), (args, named) in zip(answers, REFUSED, strict=True):
        assert rc == 2 and len(said.strip().splitlines()) == 1 and named in said, (args, rc, said)
