"""Counting what a reader end lost: every write not delivered, once — whether the writer
could not send it, or it was written while the channel was cut, or written by a restarted
writer before the channel was back. Jumps in the write numbers show most; the writer's
heartbeats tell its tail (what it could not send since its last sample), which the next
sample received reveals as a jump instead."""

from __future__ import annotations

from dataflow.transports.ends import LossCount


def feed(count: LossCount, messages: list[tuple[list[int], int | None]]) -> list[int]:
    """Feed messages (samples' write numbers; a heartbeat's tail, or None for a sample
    frame); the numbers delivered."""
    delivered = []
    for samples, tail in messages:
        delivered += [s for s in samples if count.sample(s)]
        if tail is not None:
            count.report(tail)
    return delivered


def test_a_tail_told_by_a_heartbeat_is_not_counted_again_as_the_next_jump() -> None:
    count = LossCount()
    feed(count, [([1, 2, 3], None), ([], 3)])  # the writer could not send 4, 5, 6 and said so
    assert count.lost == 3
    feed(count, [([], 3)])  # a heartbeat of a new stream: still 3
    assert count.lost == 3
    assert feed(count, [([10, 11], None)]) == [10, 11]  # 4..9 missing: 4, 5, 6 unsent, 7..9 written while cut
    assert count.lost == 6


def test_jumps_inside_a_stream_count_once() -> None:
    count = LossCount()
    feed(count, [([1, 2], None), ([5, 6], None), ([], 0), ([9], None)])
    assert count.lost == 4  # 3, 4, 7, 8


def test_samples_handed_over_again_are_not_delivered_twice() -> None:
    count = LossCount()
    assert feed(count, [([1, 2, 3], None)]) == [1, 2, 3]
    assert feed(count, [([3, 4], None)]) == [4]  # DATA seeds a new connection with the last value
    assert count.lost == 0


def test_a_restart_keeps_what_the_old_process_lost_and_counts_the_new_one_s_first_writes() -> None:
    count = LossCount()
    feed(count, [([1, 2], None), ([], 2)])  # 3, 4 not sent, not yet revealed
    count.restarted()
    assert feed(count, [([5, 6], None)]) == [5, 6]  # the new process's writes 1..4 came before the stream was back
    assert count.lost == 2 + 4


def test_counting_from_a_given_write() -> None:
    count = LossCount(after=100)  # a link made when its port had written 100 times
    assert feed(count, [([103], None)]) == [103]
    assert count.lost == 2


def test_a_heartbeat_older_than_a_sample_received_since_is_not_counted_twice() -> None:
    """The writer's tick computed its tail (after sample 3, 4 and 5 not sent), then its
    writer thread sent 6 before the heartbeat left: 6's jump counted 4 and 5 already."""
    count = LossCount()
    assert feed(count, [([1, 2, 3], None), ([6], None)]) == [1, 2, 3, 6]
    count.report(2, after=3)  # stale: it speaks of the writes after 3, and 6 came since
    assert count.lost == 2
    count.report(1, after=6)  # a fresh one: 7 not sent
    assert count.lost == 3
