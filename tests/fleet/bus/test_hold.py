"""A node's inboxes held together from a mark on (a run's snapshot): what the mark says is later waits, the rest is
queued at once, and everything held is queued on release in the order it came, its owner woken."""

import threading

from fleet.bus.session import Hold, Inbox


def _later(key: str, payload: bytes, mark: int) -> bool:
    return int(payload) >= mark


def test_only_what_comes_from_the_mark_on_is_held_and_release_queues_it_in_order():
    hold = Hold(_later)
    wake = threading.Event()
    states, parts = Inbox(wake=wake, hold=hold), Inbox(wake=wake, hold=hold)
    hold.put(states, ("state", b"5"))
    hold.start(10)
    assert hold.holding
    for inbox, item in [(states, ("state", b"10")), (parts, ("parts", b"9")), (parts, ("parts", b"11"))]:
        hold.put(inbox, item)
    hold.put(states, ("state", b"12"))
    assert list(states.items) == [("state", b"5")] and list(parts.items) == [("parts", b"9")]
    wake.clear()
    hold.release()
    assert not hold.holding and wake.is_set()
    assert states.drain() == [("state", b"5"), ("state", b"10"), ("state", b"12")]
    assert parts.drain() == [("parts", b"9"), ("parts", b"11")]
    hold.put(states, ("state", b"20"))  # released: nothing is held any more
    assert states.drain() == [("state", b"20")]


def test_items_put_from_many_threads_while_releasing_are_all_queued_once():
    hold = Hold(_later)
    inbox = Inbox(hold=hold)
    hold.start(0)
    threads = [
        threading.Thread(target=lambda i=i: [hold.put(inbox, ("k", b"%d" % (100 * i + j))) for j in range(100)])
        for i in range(4)
    ]
    for t in threads:
        t.start()
    hold.release()
    for t in threads:
        t.join()
    got = sorted(int(p) for _, p in inbox.drain())
    assert got == list(range(400))
