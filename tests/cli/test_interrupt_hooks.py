"""Issue 19 regression (found by benchmarks/interrupts.py on ``study sweep``): a Ctrl-C that cuts
short the construction of an object (pyparsing's ``Forward`` while matplotlib is imported) leaves a
half-built object whose ``__del__`` raises ``AttributeError`` later; Python printed it as "Exception
ignored ..." with a traceback after risloc's one line. Once Ctrl-C was received, such finalizer
errors are the interrupt's consequence and stay silent; before it, they are printed as usual."""

from __future__ import annotations

import signal
import types

import pytest

from risloc_rt import cli


def _unraisable(exc: BaseException):
    return types.SimpleNamespace(exc_type=type(exc), exc_value=exc, exc_traceback=None, err_msg=None, object=None)


def test_finalizer_errors_after_ctrl_c_are_silent_and_printed_before():
    seen = []
    state = {"interrupted": False}
    hook = cli._redeliver_interrupt(seen.append, state)
    hook(_unraisable(AttributeError("'Forward' object has no attribute 'expr'")))
    assert len(seen) == 1                      # no interrupt yet: printed as Python would
    state["interrupted"] = True
    hook(_unraisable(AttributeError("'Forward' object has no attribute 'expr'")))
    assert len(seen) == 1                      # after Ctrl-C: silent


def test_the_sigint_handler_notes_the_interrupt_and_raises():
    state = {"interrupted": False}
    handler = cli._note_interrupt(state)
    with pytest.raises(KeyboardInterrupt):
        handler(signal.SIGINT, None)
    assert state["interrupted"] is True


def test_a_ctrl_c_in_a_finalizer_is_delivered_again(monkeypatch):
    calls = []
    monkeypatch.setattr("_thread.interrupt_main", lambda *a: calls.append(a))
    cli._redeliver_interrupt(lambda u: pytest.fail("must not print"), {"interrupted": False})(
        _unraisable(KeyboardInterrupt()))
    assert calls == [()]
