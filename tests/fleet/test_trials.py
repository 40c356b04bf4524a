"""A physical pick: the part ends in the bin, carried only by friction between the fingers."""

from fleet.trials import run_trial


def test_a_few_seeded_openclaw_picks_succeed():
    results = [run_trial("openclaw", seed) for seed in range(3)]
    assert all(r.success for r in results), results
