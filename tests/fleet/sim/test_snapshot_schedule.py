"""Which snapshot every state and frame names as the next (each node holds what it is sent from that tick on): the
nearest scheduled one after the tick, never one at or after the run's end (it is never taken, and a node told of it
would hold the line's last events)."""

from types import SimpleNamespace

from fleet.sim.sim_snapshot import RunFacts, SimSnapshots


def schedule(at: set[int], every: int, end: int) -> SimSnapshots:
    sim = SimpleNamespace(cadence=SimpleNamespace(coord_period_ticks=10, max_period_ticks=100))
    return SimSnapshots(sim, RunFacts("pick_cell", None, "optimal", end), None, at, every)


def test_the_next_snapshot_is_the_nearest_after_the_tick_and_before_the_end():
    s = schedule({300, 1000}, 0, 1000)
    assert [s.next_due(t) for t in (0, 299, 300, 999)] == [300, 300, -1, -1]
    s = schedule({450}, 200, 1000)
    assert [s.next_due(t) for t in (0, 200, 401, 450, 799, 800)] == [200, 400, 450, 600, 800, -1]
