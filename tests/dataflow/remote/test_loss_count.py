"""Counting what a subscriber lost: every write not delivered, once — whether the server
dropped it, or it was written while the stream was cut, or both (the server reported a
drop at the end of a stream, and the next stream's first sample shows the same write as
a jump)."""

from __future__ import annotations

from dataflow.remote._loss import LossCount


def feed(count: LossCount, messages: list[tuple[list[int], int]]) -> list[int]:
    """Feed one stream's messages (samples' write numbers, the server's drop count); the
    numbers delivered."""
    count.new_stream()
    delivered = []
    for samples, dropped in messages:
        delivered += [s for s in samples if count.sample(s, dropped)]
        count.report(dropped)
    return delivered


def test_drops_reported_at_a_stream_end_are_not_counted_again_as_the_next_jump() -> None:
    count = LossCount()
    feed(count, [([1, 2, 3], 0), ([], 3)])  # the server dropped 4, 5, 6 and said so; then the stream broke
    assert count.lost == 3
    feed(count, [([], 0)])  # a new stream's heartbeat: still 3 (not 0 until a sample shows the jump)
    assert count.lost == 3
    assert feed(count, [([10, 11], 0)]) == [10, 11]  # 4..9 missing: 4, 5, 6 dropped, 7..9 written while cut
    assert count.lost == 6


def test_drops_inside_a_stream_count_once() -> None:
    count = LossCount()
    feed(count, [([1, 2], 0), ([5, 6], 2), ([9], 4)])
    assert count.lost == 4  # 3, 4, 7, 8


def test_a_stream_s_own_early_drops_and_a_reconnection_jump() -> None:
    count = LossCount()
    feed(count, [([1], 0)])
    feed(count, [([8, 9], 2), ([12], 4)])  # 2..7 missing (2 dropped on this stream), then 10, 11 dropped
    assert count.lost == 6 + 2


def test_samples_handed_over_again_are_not_delivered_twice() -> None:
    count = LossCount()
    assert feed(count, [([1, 2, 3], 0)]) == [1, 2, 3]
    assert feed(count, [([3, 4], 0)]) == [4]  # DATA seeds a new connection with the last value
    assert count.lost == 0


def test_a_restart_keeps_what_the_old_process_lost_and_starts_numbers_over() -> None:
    count = LossCount()
    feed(count, [([1, 2], 0), ([], 2)])  # 3, 4 dropped, not yet revealed
    count.restarted()
    assert feed(count, [([1, 2], 0)]) == [1, 2]
    assert count.lost == 2
