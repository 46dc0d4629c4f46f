"""A call beside the caller's (:func:`ftrac_design.threads.beside`): its value, its exception
on the caller's thread, and work that lets go of the interpreter done at the same time."""

from __future__ import annotations

import threading

import pytest

from ftrac_design.threads import beside


def test_the_value_comes_back_and_the_call_ran_on_another_thread():
    caller = threading.get_ident()
    job = beside(lambda a, b=0: (a + b, threading.get_ident()), 2, b=3)
    value, ran_on = job.result()
    assert value == 5 and ran_on != caller


def test_an_exception_is_raised_on_the_callers_thread_with_its_type_and_message():
    def fails():
        raise MemoryError("no room for the map")

    job = beside(fails)
    with pytest.raises(MemoryError, match="no room for the map"):
        job.result()


def test_both_sides_run_at_once():
    """The two sides wait for each other: were the call run after the caller's part (or the
    caller's after the call), the first to wait would wait forever, and this would time out."""
    here, there = threading.Event(), threading.Event()

    def other() -> bool:
        there.set()
        return here.wait(10.0)

    job = beside(other)
    assert there.wait(10.0)
    here.set()
    assert job.result() is True
