"""A line whose nodes run on separate hosts (network namespaces the test makes), first over plain TCP, then with
Zenoh's TLS, a login per node and access control: the two runs give one summary, and a process without a login, or
logged in as another arm's controller, cannot stop the line or move an arm."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.fleet.hosts_apart.namespaces import NamespacesUnavailable, hosts_on_one_switch, processes_in
from tests.fleet.test_run import QUICK_LINE, WALL_FIGURES

pytestmark = pytest.mark.slow  # whole runs, processes or a browser: `-m "not slow"` leaves them out

INTRUDER = str(Path(__file__).parent / "intruder.py")


@pytest.fixture(scope="module")
def hosts():
    try:
        with hosts_on_one_switch(["simhost", "coordhost", "armhost", "desk"]) as made:
            yield made
    except NamespacesUnavailable as exc:
        pytest.skip(f"cannot make network namespaces here: {exc}")


def bus_configs(tmp_path: Path, hosts, secure: bool) -> str:
    out = tmp_path / ("secure" if secure else "plain")
    argv = [
        "bus-config",
        "--address",
        hosts["simhost"].address,
        "--port",
        "7447",
        "--scene",
        QUICK_LINE,
        "--out",
        str(out),
    ]
    made = subprocess.run(
        [sys.executable, "-m", "fleet", *argv, *([] if secure else ["--insecure"])], capture_output=True, text=True
    )
    assert made.returncode == 0, made.stderr
    return str(out)


def hosts_file(tmp_path: Path, hosts) -> str:
    path = tmp_path / "hosts.yaml"
    nodes = {"sim": "simhost", "coordinator": "coordhost", "arm_0": "armhost", "arm_1": "armhost"}
    path.write_text("nodes:\n" + "".join(f"  {node}: {hosts[h].netns}\n" for node, h in nodes.items()))
    return str(path)


def run_from_the_desk(hosts, bus: str, hosts_yaml: str) -> subprocess.Popen:
    """`fleet run` started on the desk host; the launcher starts each node on its own host."""
    argv = ["run", QUICK_LINE, "--duration", "18", "--seed", "5", "--bus-config", bus, "--hosts", hosts_yaml, "--json"]
    return subprocess.Popen(
        hosts["desk"].run(sys.executable, "-m", "fleet", *argv),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def summary_of(proc: subprocess.Popen, timeout_s: float = 180.0) -> dict:
    """The run's summary; a run that does not end in time is stopped (SIGTERM: the launcher stops its nodes)."""
    try:
        out, err = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.terminate()
        out, err = proc.communicate(timeout=30)
        pytest.fail(f"the run did not end within {timeout_s:.0f} s (stopped): {err[-2000:]}")
    assert proc.returncode == 0, err[-3000:]
    summary = json.loads(out.strip().splitlines()[-1])
    # runs on either bus compare, but for what the secure one's router refused
    return {k: v for k, v in summary.items() if k not in (*WALL_FIGURES, "bus")}


def test_a_line_on_separate_hosts_runs_as_on_one_and_with_tls_logins_and_acl_no_intruder_stops_or_moves_an_arm(
    tmp_path, hosts
):
    hosts_yaml = hosts_file(tmp_path, hosts)
    plain = summary_of(run_from_the_desk(hosts, bus_configs(tmp_path, hosts, secure=False), hosts_yaml))
    assert plain["status"] == "ok" and plain["parts_completed"] >= 2 and plain["inter_arm_contacts"] == 0

    secure_bus = bus_configs(tmp_path, hosts, secure=True)
    no_login = tmp_path / "no_login.json5"  # the CA to trust the sim, but no user and password
    config = json.loads(Path(secure_bus, "arm_1.json5").read_text())
    del config["transport"]["auth"]
    no_login.write_text(json.dumps(config))
    line = run_from_the_desk(hosts, secure_bus, hosts_yaml)
    intruders = [
        subprocess.Popen(
            hosts["armhost"].run(sys.executable, INTRUDER, "--config", config, "--seconds", "3", "--connect-within", c),
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for config, c in ((str(Path(secure_bus, "arm_1.json5")), "60"), (str(no_login), "8"))
    ]
    try:
        as_arm_1, without_login = [
            json.loads(p.communicate(timeout=120)[0].strip().splitlines()[-1]) for p in intruders
        ]
        secure = summary_of(line)
    finally:
        for proc in (*intruders, line):
            if proc.poll() is None:
                proc.terminate()
                proc.wait(30)

    assert without_login["connected"] is False, "the router lets in no one without a login"
    assert as_arm_1["connected"] and as_arm_1["heard_states"] > 0 and as_arm_1["sent"] > 0, (
        "logged in as arm_1: it hears the line"
    )
    refused = secure.pop("bus_refused")
    assert plain.pop("bus_refused") == {}, "a bus without access control refuses nothing"
    assert secure == plain, "e-stop, pause, goals and orders for arm_0 from arm_1's login never reached anyone"
    for key in ("estop", "arm/arm_0/goal"):
        assert refused.get(f"arm_1: put on clawfleet/line/{key}", 0) >= 1, ("counted by the router", key, refused)
    for host in hosts.values():
        assert processes_in(host.netns) == [], f"processes left on {host.netns}"
