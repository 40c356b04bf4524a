"""Suite-wide: robots a test registers (a robot file, a tuning candidate) are gone after it, so that no test sees
another's robots (a scene error lists the valid models)."""

import pytest

import robots.registry


@pytest.fixture(autouse=True)
def robots_registered_by_a_test_stay_in_it(monkeypatch):
    robots.registry._load_entry_points()  # the installed packages' robots belong to every test
    monkeypatch.setattr(robots.registry, "_REGISTRY", dict(robots.registry._REGISTRY))
