"""Network faults drawn per link from the run's seed, and the flights they make of a link's states."""

import argparse

import pytest

from fleet.bus.faults import FaultyLink, Passage, add_fault_arguments, links_for, network_from_args, ticks_for
from fleet.bus.flights import FlightBook
from scenes.schema import LinkFaults, Network


def test_a_links_draws_repeat_for_a_seed_and_differ_between_links():
    def draws(seed: int, index: int) -> list:
        link = FaultyLink("arm_0", LinkFaults(latency_ms=20, jitter_ms=5, loss=0.1), seed, index)
        return [link.passage("down") for _ in range(200)]

    assert draws(3, 0) == draws(3, 0)
    assert draws(3, 0) != draws(3, 1) and draws(3, 0) != draws(4, 0)


def test_loss_and_delay_are_counted_and_near_what_was_asked():
    link = FaultyLink("coordinator", LinkFaults(latency_ms=50, jitter_ms=5, loss=0.02), 0, 0)
    fates = [link.passage("up") for _ in range(20_000)]
    lost = sum(f.lost for f in fates)
    assert link.counts["up_sent"] == 20_000 and link.counts["up_lost"] == lost
    assert 0.015 < lost / 20_000 < 0.025
    report = link.report()
    assert 49.5 < report["up"]["mean_delay_ms"] < 50.5
    assert report["down"] == {"mean_delay_ms": 0.0}


def test_without_faults_nothing_is_lost_or_late():
    link = links_for(None, ["arm_0", "coordinator"], 0)["arm_0"]
    assert not link.active
    assert all(link.passage("down") == Passage(False, 0.0) for _ in range(100))


def test_a_delay_in_lockstep_is_whole_ticks_never_early():
    assert ticks_for(0.0, 100) == 0
    assert ticks_for(0.030, 100) == 3
    assert ticks_for(0.0301, 100) == 4


def test_a_flight_arrives_after_the_delay_and_its_answer_takes_effect_a_period_and_the_way_back_later():
    book = FlightBook(FaultyLink("arm_0", LinkFaults(latency_ms=30), 0, 0), hz=100)
    flight = book.send(10, "state@10", period_ticks=5, now_wall_s=0.0, lockstep=True)
    assert (flight.deliver_tick, flight.apply_tick) == (13, 21)
    assert book.deliver(12, 0.0, True) is None
    assert book.deliver(13, 0.0, True) is flight
    assert book.awaiting() is flight
    assert book.answer(10, "answer") is flight and book.awaiting() is None
    assert book.due_answers(20) == []
    assert book.due_answers(21) == [flight]


def test_without_faults_a_state_arrives_when_sampled_and_is_answered_one_period_later():
    book = FlightBook(FaultyLink("arm_0", LinkFaults(), 0, 0), hz=100)
    flight = book.send(10, "s", period_ticks=5, now_wall_s=0.0, lockstep=True)
    assert (flight.deliver_tick, flight.apply_tick) == (10, 15)


def test_of_states_arriving_together_only_the_newest_is_delivered_and_the_older_counted_as_overtaken():
    link = FaultyLink("arm_0", LinkFaults(), 0, 0)
    book = FlightBook(link, hz=100)
    book.send(0, "a", 5, 0.0, True)
    book.send(1, "b", 5, 0.0, True)
    assert book.deliver(1, 0.0, True).message == "b"
    assert link.counts["down_overtaken"] == 1
    assert book.answer(0, "late answer") is None, "an overtaken state is never awaited"


def test_an_answer_lost_on_the_way_back_is_recorded_then_forgotten():
    book = FlightBook(FaultyLink("arm_0", LinkFaults(loss=0.5), 0, 0), hz=100)
    flights = [book.send(t, "s", 5, 0.0, True) for t in range(50)]
    assert 10 < flights.count(None) < 40, "lost on the way out"
    survivor = next(f for f in flights if f is not None and f.up_lost)
    book.flights = {survivor.tick: survivor}
    book.deliver(survivor.tick, 0.0, True)
    assert book.answer(survivor.tick, "answer") is survivor
    assert book.awaiting() is None and book.due_answers(10_000) == []


@pytest.mark.parametrize(
    "flags, problem",
    [
        (["--loss", "1.5"], "--loss 1.5"),
        (["--latency-ms", "-1"], "--latency-ms -1"),
        (["--jitter-ms", "nan"], "--jitter-ms nan"),
    ],
)
def test_bad_fault_flags_name_the_flag(flags, problem):
    parser = argparse.ArgumentParser()
    add_fault_arguments(parser)
    with pytest.raises(ValueError, match=problem):
        network_from_args(parser.parse_args(flags))


def test_fault_flags_set_every_link():
    parser = argparse.ArgumentParser()
    add_fault_arguments(parser)
    network = network_from_args(parser.parse_args(["--latency-ms", "20", "--loss", "0.01"]))
    assert network.link("arm_3") == LinkFaults(latency_ms=20, loss=0.01)
    assert network_from_args(parser.parse_args([])) is None


def test_a_link_of_its_own_replaces_the_defaults():
    network = Network(latency_ms=10, links={"coordinator": LinkFaults(loss=0.5)})
    assert network.link("coordinator") == LinkFaults(loss=0.5)
    assert network.link("arm_0") == LinkFaults(latency_ms=10)
