"""The queue of host lines waiting for their answers (``xac1_proto.waiting``): ``due`` is a time no
window closes before, whatever lines entered and left, and ``closed`` is the one judgement of a closed
window."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from xac1_proto.waiting import COMMAND, Waiting, WaitingLine

# what happens to the queue: a line sent at t waiting w seconds, its answer taken, or time passing to t
steps = st.lists(st.one_of(
    st.tuples(st.just("send"), st.floats(0, 100), st.floats(0.01, 50)),
    st.tuples(st.just("answer"), st.floats(0, 100), st.just(0.0)),
    st.tuples(st.just("time"), st.floats(0, 200), st.just(0.0)),
), max_size=40)


@given(steps)
def test_no_window_closes_before_due_and_closed_takes_exactly_the_closed_ones(script):
    """Lines enter (``append``), leave as their answers come (``take_own_answer``) and close as time
    passes (``closed``): at every step no waiting line's deadline is before ``due``; ``closed(now)``
    takes exactly the lines whose deadline is before ``now``, in order, and when it takes any, leaves
    ``due`` the earliest deadline of those left (infinity when none is)."""
    queue = Waiting()
    for i, (what, t, window) in enumerate(script):
        if what == "send":
            queue.append(WaitingLine(i, COMMAND, "0RV", None, t, window))
        elif what == "answer":
            head = queue.head
            taken = queue.take_own_answer("0RV", t)
            assert taken is (head if head is not None and head.t_last is not None
                             and head.t_last <= t else None)
        else:
            before = list(queue)
            closed = queue.closed(t, None)
            assert closed == [w for w in before if w.deadline is not None and w.deadline < t]
            assert list(queue) == [w for w in before if w not in closed]
            if closed:
                assert queue.due == min((w.deadline for w in queue if w.deadline is not None),
                                        default=float("inf"))
        assert all(w.deadline is None or queue.due <= w.deadline for w in queue)


def test_an_answer_in_time_keeps_the_head_open_while_it_arrives():
    """An answer that began within the head's window closes nothing, even after the window's end (an
    answer that starts in time is in time); without one the head closes."""
    queue = Waiting()
    line = WaitingLine(0, COMMAND, "0RV", None, 1.0, 0.5)
    queue.append(line)
    assert queue.closed(2.0, since=1.2) == []
    assert queue.closed(2.0, since=None) == [line]
    assert not queue and queue.due == float("inf")
