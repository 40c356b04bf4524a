"""A line's bus across hosts: the sim's session is the router every other node logs in to as a client.

Zenoh peers do not relay for one another, so nodes on different hosts meet at one router: the
sim's own session (no extra process). `write_bus_configs` writes one Zenoh config per node
(`fleet bus-config`): by default with TLS (a CA and the sim's certificate, made here with
`cryptography`), a user and password per node, and access control on the router, so that only
the sim publishes what the arms and the line report, only the coordinator gives orders, each
controller drives only its own arm, and only the monitor stops or paces the line. Usernames are
node names: `sim`, `coordinator`, `launcher`, `monitor`, `recorder`, `ros` (the ROS front ends), `ros_client` (an
outside ROS 2 stack on rmw_zenoh), `perception`, and each arm's id.
"""

from __future__ import annotations

import datetime
import ipaddress
import json
import os
import secrets
from dataclasses import dataclass
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import NameOID

from fleet.bus.keys import ROOT
from scenes.schema import is_valid_name

MANIFEST = "bus.json"
SERVICE_NODES = (
    "coordinator",
    "launcher",
    "monitor",
    "recorder",
    "ros",
    "ros_client",
    "perception",
    "twin",
)  # every node but the sim and the arms' controllers
ANY_RUN = f"{ROOT}/*"
# what each client may publish (ingress at the router); `{arm}` is the controller's own arm
PUBLISHES = {
    "coordinator": ("arm/*/assign", "coord/**", "snapshot/coordinator"),
    "monitor": ("estop", "world/control", "launcher/respawn"),
    "recorder": ("recorder/ready",),
    "perception": ("perception/*", "seen/parts", "seen/ready"),  # each camera's tracks; the line's parts it sees
    "launcher": ("launcher/roster",),
    "ros": ("arm/*/drive", "estop", "world/control"),  # the ROS front ends: outside goals, e-stop, pause
    "twin": ("arm/*/drive",),  # `fleet twin serve-bus`: an outside driver's goals to the arm its servos stand for
    "ros_client": (),  # a ROS 2 stack: nothing of clawfleet's own; the line's ROS services and actions (`--ros2`)
    "controller": ("arm/{arm}/step", "arm/{arm}/goal", "arm/{arm}/status", "snapshot/{arm}"),
}


class BusConfigError(ValueError):
    """A bus config directory or request that cannot be used; the message is one line."""


@dataclass(frozen=True)
class BusConfigSet:
    """The configs `write_bus_configs` wrote: the sim's endpoint and one Zenoh config file per node."""

    directory: Path
    endpoint: str
    secure: bool
    arms: tuple[str, ...]

    def config_for(self, node: str) -> str:
        """The Zenoh config file of `node` (`sim`, a service node or an arm id)."""
        valid = ("sim", *SERVICE_NODES, *self.arms)
        if node not in valid:
            raise BusConfigError(f"no bus config for {node!r} in {self.directory}; nodes: {', '.join(valid)}")
        return str(self.directory / f"{node}.json5")

    @classmethod
    def load(cls, directory: str | Path) -> BusConfigSet:
        path = Path(directory) / MANIFEST
        try:
            manifest = json.loads(path.read_text())
            made = cls(
                Path(directory).resolve(), manifest["endpoint"], bool(manifest["secure"]), tuple(manifest["arms"])
            )
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise BusConfigError(
                f"{path}: not a bus config directory written by `fleet bus-config` ({exc.__class__.__name__}: {exc})"
            ) from None
        missing = [n for n in ("sim", *SERVICE_NODES, *made.arms) if not Path(made.config_for(n)).is_file()]
        if missing:
            raise BusConfigError(
                f"{directory}: no config for {', '.join(missing)} (write it again with `fleet bus-config`)"
            )
        return made


def write_bus_configs(
    out: str | Path,
    address: str,
    port: int,
    arms: list[str],
    *,
    secure: bool = True,
    valid_days: int = 365,
    ros_domain: int | None = None,
    ros_arms: tuple[str, ...] | None = None,
) -> BusConfigSet:
    """One Zenoh config per node in `out`: the sim a router listening on `address:port`, every other node a
    client of it; with `secure`, TLS, logins and access control (private keys and passwords readable by the
    owner only). With `ros_domain`, the router lets the line's native ROS 2 graph through (`access_control`)."""
    ip = _checked_request(address, port, arms, ros_arms)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    endpoint = f"{'tls' if secure else 'tcp'}/{address}:{port}"
    nodes = ("sim", *SERVICE_NODES, *arms)
    if secure:
        passwords = {n: secrets.token_urlsafe(24) for n in nodes if n != "sim"}
        tls = _write_certificates(out, ip, valid_days)
        _write_private(out / "users.txt", "".join(f"{n}:{p}\n" for n, p in passwords.items()))
    # scouting off: every node is told where the router is; no delay either (Zenoh's router waits 0.5 s at open for
    # peers it would scout, the whole of a secure run's extra start-up)
    router = {
        "mode": "router",
        "listen": {"endpoints": [endpoint]},
        "connect": {"endpoints": []},
        "scouting": {"delay": 0},
    }
    if secure:
        router["transport"] = {
            "link": {
                "tls": tls | {"listen_certificate": str(out / "sim.pem"), "listen_private_key": str(out / "sim.key")}
            },
            "auth": {"usrpwd": {"dictionary_file": str(out / "users.txt")}},
        }
        router["access_control"] = access_control(arms, ros_domain, ros_arms)
    _write_private(out / "sim.json5", json.dumps(router, indent=2))
    for node in nodes[1:]:
        client = {"mode": "client", "connect": {"endpoints": [endpoint]}}
        if secure:
            client["transport"] = {
                "link": {"tls": tls},
                "auth": {"usrpwd": {"user": node, "password": passwords[node]}},
            }
        _write_private(out / f"{node}.json5", json.dumps(client, indent=2))
    (out / MANIFEST).write_text(json.dumps({"endpoint": endpoint, "secure": secure, "arms": list(arms)}, indent=2))
    return BusConfigSet(out.resolve(), endpoint, secure, tuple(arms))


def _checked_request(
    address: str, port: int, arms: list[str], ros_arms: tuple[str, ...] | None
) -> ipaddress.IPv4Address | ipaddress.IPv6Address:
    """The sim's address, once the request is one configs can be written for; else `BusConfigError`."""
    try:
        ip = ipaddress.ip_address(address)
    except ValueError:
        raise BusConfigError(f"--address {address!r}: an IP address of the sim's host, e.g. 10.0.0.5") from None
    if not 0 < port < 65536:
        raise BusConfigError(f"--port {port}: a TCP port, 1..65535")
    bad = [a for a in arms if not is_valid_name(a) or a in ("sim", *SERVICE_NODES)]
    if bad or not arms:
        raise BusConfigError(
            f"arm ids {bad or arms}: need at least one, lower-case identifiers, none named like a node"
        )
    if ros_arms is not None and (not ros_arms or not set(ros_arms) <= set(arms)):
        raise BusConfigError(f"--ros-arms {','.join(ros_arms)}: give some of this line's arms ({', '.join(arms)})")
    return ip


def write_run_bus(
    folder: str | Path,
    arms: list[str],
    port: int,
    ros_domain: int | None = None,
    ros_arms: tuple[str, ...] | None = None,
) -> BusConfigSet:
    """A run's own secure bus on loopback (what `fleet run` does unless told `--insecure`): TLS, a login per node and
    access control, written into the run's private folder (the folder and every file holding a key or a password
    readable by the owner only). Nothing but the run's own processes, and a client given one of these configs,
    can log in."""
    folder = Path(folder)
    folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    os.chmod(folder, 0o700)
    return write_bus_configs(
        folder, "127.0.0.1", port, arms, secure=True, valid_days=2, ros_domain=ros_domain, ros_arms=ros_arms
    )


def access_control(arms: list[str], ros_domain: int | None = None, ros_arms: tuple[str, ...] | None = None) -> dict:
    """The router's rules: everything logged in may listen and ask (the sim's queryables answer); each may
    publish only its own keys (`PUBLISHES`); nothing else, and no client may serve a queryable. With `ros_domain`,
    the line's native ROS graph too (`ros2_rules`)."""
    keys = lambda patterns, arm="": [f"{ANY_RUN}/{p.format(arm=arm)}" for p in patterns]  # noqa: E731
    rules = [
        {
            "id": "deliver",
            "permission": "allow",
            "flows": ["egress"],
            "messages": ["put", "delete", "declare_subscriber", "declare_queryable", "query", "reply"],
            "key_exprs": [f"{ROOT}/**"],
        },
        {
            "id": "listen",
            "permission": "allow",
            "flows": ["ingress"],
            "messages": ["declare_subscriber", "query"],
            "key_exprs": [f"{ROOT}/**"],
        },
    ]
    subjects = [{"id": "everyone", "usernames": [*SERVICE_NODES, *arms]}]
    policies = [{"rules": ["deliver", "listen"], "subjects": ["everyone"]}]
    publishers = {n: keys(PUBLISHES[n]) for n in SERVICE_NODES} | {a: keys(PUBLISHES["controller"], a) for a in arms}
    for node, exprs in publishers.items():
        if exprs:
            rules.append(
                {
                    "id": f"publish_{node}",
                    "permission": "allow",
                    "flows": ["ingress"],
                    "messages": ["put"],
                    "key_exprs": exprs,
                }
            )
            subjects.append({"id": node, "usernames": [node]})
            policies.append({"rules": [f"publish_{node}"], "subjects": [node]})
    if ros_domain is not None:
        commanded = tuple(arms if ros_arms is None else ros_arms)
        ros_rules, ros_policies = ros2_rules(ros_domain, commanded, set(commanded) >= set(arms))
        rules += ros_rules
        policies[0]["rules"] += ["ros2_deliver", "ros2_listen", "ros2_caches", "ros2_discovery"]
        policies += ros_policies
        subjects.append({"id": "ros_client", "usernames": ["ros_client"]})
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects, "policies": policies}


def ros2_rules(domain: int, commanded: tuple[str, ...], every_arm: bool) -> tuple[list[dict], list[dict]]:
    """The native ROS 2 graph (`fleet.ros.rmw_zenoh`): every login may listen, discover, declare its own graph
    entities and read latched topics' caches; only `ros` (the line's ROS 2 node) publishes and serves; only
    `ros_client` (an outside ROS 2 stack) calls the e-stop, and the actions of, and publishes trajectories to,
    the `commanded` arms (pause and resume when it is given every arm)."""
    data, caches = f"{domain}/**", f"{domain}/**/@adv/**"  # `@adv`: chunks `**` does not reach
    ros2 = [data, caches, "@ros2_lv/**"]
    listen = ["declare_subscriber", "declare_liveliness_subscriber", "liveliness_query"]
    calls = [
        f"{domain}/{arm}/{action}/_action/**"
        for arm in commanded
        for action in ("follow_joint_trajectory", "gripper_cmd")
    ]
    calls += [f"{domain}/{service}/**" for service in ("estop", "pause", "resume")[: 3 if every_arm else 1]]
    rules = [
        {"id": "ros2_deliver", "permission": "allow", "flows": ["egress"],
         "messages": [*listen, "query", "put", "delete", "reply", "liveliness_token", "declare_queryable"],
         "key_exprs": ros2},
        {"id": "ros2_listen", "permission": "allow", "flows": ["ingress"], "messages": listen, "key_exprs": ros2},
        {"id": "ros2_caches", "permission": "allow", "flows": ["ingress"], "messages": ["query"],
         "key_exprs": [caches]},
        {"id": "ros2_discovery", "permission": "allow", "flows": ["ingress"],  # ROS nodes say they exist
         "messages": ["liveliness_token"], "key_exprs": ["@ros2_lv/**"]},
        {"id": "ros2_publish", "permission": "allow", "flows": ["ingress"],  # topics, services, latched caches
         "messages": ["put", "delete", "declare_queryable", "reply", "liveliness_token"], "key_exprs": [data, caches]},
        {"id": "ros2_command", "permission": "allow", "flows": ["ingress"], "messages": ["query"], "key_exprs": calls},
        {"id": "ros2_drive", "permission": "allow", "flows": ["ingress"], "messages": ["put"],
         "key_exprs": [f"{domain}/{arm}/joint_trajectory/**" for arm in commanded]},
    ]  # fmt: skip
    policies = [
        {"rules": ["ros2_publish"], "subjects": ["ros"]},
        {"rules": ["ros2_command", "ros2_drive"], "subjects": ["ros_client"]},
    ]
    return rules, policies


def _write_certificates(out: Path, ip: ipaddress.IPv4Address | ipaddress.IPv6Address, valid_days: int) -> dict:
    """A CA and the sim's certificate for `ip` (what clients check it by); the clients' TLS settings."""
    now = datetime.datetime.now(datetime.timezone.utc)
    ca_key, sim_key = ec.generate_private_key(ec.SECP256R1()), ec.generate_private_key(ec.SECP256R1())
    ca_name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "clawfleet bus CA")])
    valid = dict(
        not_valid_before=now - datetime.timedelta(minutes=5), not_valid_after=now + datetime.timedelta(days=valid_days)
    )
    ca = (
        x509.CertificateBuilder(
            subject_name=ca_name,
            issuer_name=ca_name,
            public_key=ca_key.public_key(),
            serial_number=x509.random_serial_number(),
            **valid,
        )
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=True,
                key_cert_sign=True,
                crl_sign=True,
                content_commitment=False,
                key_encipherment=False,
                data_encipherment=False,
                key_agreement=False,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )
        .sign(ca_key, hashes.SHA256())
    )
    sim = (
        x509.CertificateBuilder(
            subject_name=x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "sim")]),
            issuer_name=ca_name,
            public_key=sim_key.public_key(),
            serial_number=x509.random_serial_number(),
            **valid,
        )
        .add_extension(x509.SubjectAlternativeName([x509.IPAddress(ip)]), critical=False)
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .sign(ca_key, hashes.SHA256())
    )
    (out / "ca.pem").write_bytes(ca.public_bytes(serialization.Encoding.PEM))
    (out / "sim.pem").write_bytes(sim.public_bytes(serialization.Encoding.PEM))
    pkcs8 = sim_key.private_bytes(
        serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()
    )
    _write_private(out / "sim.key", pkcs8.decode())
    return {"root_ca_certificate": str(out / "ca.pem")}


def _write_private(path: Path, text: str) -> None:
    """Write a file only its owner may read (keys, passwords, configs that hold one)."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write(text)
    os.chmod(path, 0o600)
