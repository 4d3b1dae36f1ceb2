"""The in-process event bus: newest state per kind, bounded per reader, listeners isolated."""

import threading

from flask_move_server.core.events import EventBus


def test_a_subscriber_reads_events_in_order_of_kind():
    bus = EventBus()
    sub = bus.subscribe()
    bus.publish("mode", {"mode": "mapping"})
    bus.publish("pose", {"x": 1})
    assert sub.next(0.1) == ("mode", {"mode": "mapping"})
    assert sub.next(0.1) == ("pose", {"x": 1})
    assert sub.next(0.01) is None


def test_a_slow_reader_keeps_only_the_newest_of_each_kind():
    bus = EventBus()
    sub = bus.subscribe()
    for x in range(10000):
        bus.publish("pose", {"x": x})
    bus.publish("waypoints", {"version": 3})
    assert sub.next(0.1) == ("pose", {"x": 9999})
    assert sub.next(0.1) == ("waypoints", {"version": 3})
    assert sub.next(0.01) is None


def test_a_new_subscriber_is_primed_with_the_latest_state():
    bus = EventBus()
    bus.publish("mode", {"mode": "idle"})
    bus.publish("mode", {"mode": "navigation"})
    sub = bus.subscribe(kinds=["mode"])
    assert sub.next(0.1) == ("mode", {"mode": "navigation"})
    assert bus.latest("mode") == {"mode": "navigation"}


def test_kinds_filter_what_a_subscriber_hears():
    bus = EventBus()
    sub = bus.subscribe(kinds=["estop"], replay=False)
    bus.publish("pose", {"x": 1})
    bus.publish("estop", {"latched": True})
    assert sub.next(0.1) == ("estop", {"latched": True})
    assert sub.next(0.01) is None


def test_closing_wakes_a_waiting_reader_and_unsubscribes():
    bus = EventBus()
    sub = bus.subscribe()
    got = []
    reader = threading.Thread(target=lambda: got.append(sub.next(30)))
    reader.start()
    sub.close()
    reader.join(5)
    assert got == [None] and bus.subscribers == 0


def test_a_failing_listener_neither_breaks_the_publisher_nor_the_others():
    bus = EventBus()
    heard = []
    bus.listen("map", lambda data: 1 / 0)
    bus.listen("map", heard.append)
    bus.publish("map", {"version": 2})
    assert heard == [{"version": 2}]
