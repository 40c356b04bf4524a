"""Suite-wide: robots a test registers (a robot file, a tuning candidate) are gone after it, so that no test sees
another's robots (a scene error lists the valid models); the lines tests run in this process fork their nodes from
one kept node factory, as a sweep's worker does (a run's own factory costs ~2 s of imports, and the suite runs
dozens of lines); the tests that need a Ray cluster share one head, in a network namespace whose only interface is
loopback (each a head of its own cost ~9 s)."""

import pytest

import robots.registry
from fleet.run.node_factory import close_kept_factory, keep_factory
from tests.ray_namespace import loopback_namespace, start_head


@pytest.fixture(autouse=True, scope="session")
def lines_fork_their_nodes_from_one_kept_factory():
    keep_factory()
    yield
    close_kept_factory()


@pytest.fixture(autouse=True)
def robots_registered_by_a_test_stay_in_it(monkeypatch):
    robots.registry._load_entry_points()  # the installed packages' robots belong to every test
    monkeypatch.setattr(robots.registry, "_REGISTRY", dict(robots.registry._REGISTRY))


@pytest.fixture(scope="session")
def ray_head() -> str:
    """The address of a Ray head in the loopback namespace, started when a test first asks for it."""
    pytest.importorskip("ray")
    with loopback_namespace():
        yield start_head()
