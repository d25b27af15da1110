"""
A stop asked for by SIGINT (Ctrl-C) or SIGTERM while an ``extended-tracker`` command runs.

The command line's handler raises an exception in the main thread, ``KeyboardInterrupt``
for SIGINT and :class:`Terminated` for SIGTERM, so cleanups run: a half-written bag's
staging folder is removed. An exception that a signal handler raises can be lost,
though: C code running at that moment may clear it. An extension module's import did
(numpy.random's, the first thing a simulation does): of signals sent just after
``simulate`` started its bag, about one SIGTERM in 30 and one SIGINT in 30 were dropped
there, and the command wrote its whole bag and ended with status 0.

So the handler also records the signal, and the places that decide a command's outcome
look at it with :func:`check`: every scan of a bag being written or replayed and of the
scenarios ``results`` runs, the move of a finished bag into place
(:func:`bagio.staged_bag`), and the end of the command. Outside the command line (and
after a command ends) no signal is recorded and :func:`check` does nothing.

:func:`take`, :func:`unblock` and :func:`give_back` install and remove handlers for both
signals: the command line's :func:`on_signal`, and the node's, which only asks its spin
loop to stop (:mod:`ros.entry`).
"""

from __future__ import annotations

import signal

#: the signals the command line takes over, each with the exception it raises
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Terminated(BaseException):
    """SIGTERM arrived: raised in the main thread so cleanups run, as for Ctrl-C."""


_received: list = []                    # the signals received since :func:`reset`


def _stop(signum) -> BaseException:
    return KeyboardInterrupt() if signum == signal.SIGINT else Terminated()


def on_signal(signum, frame):
    """The handler of :data:`STOP_SIGNALS`: record the signal, then raise its exception."""
    _received.append(signum)
    raise _stop(signum)


def check() -> None:
    """Raise the first recorded signal's exception again (its first may have been lost)."""
    if _received:
        raise _stop(_received[0])


def received() -> int | None:
    """The first stop signal received since :func:`reset`, or None."""
    return _received[0] if _received else None


def reset() -> None:
    """Forget earlier signals (a new command starts)."""
    _received.clear()


def take(handler) -> tuple:
    """Make ``handler`` the handler of :data:`STOP_SIGNALS`; return the handlers they had
    and this thread's signal mask, for :func:`give_back` (:func:`unblock` changes it)."""
    handlers = {sig: signal.signal(sig, handler) for sig in STOP_SIGNALS}
    return handlers, signal.pthread_sigmask(signal.SIG_BLOCK, [])


def unblock() -> None:
    """
    Unblock :data:`STOP_SIGNALS` in this thread.

    A blocked mask is inherited across exec, so a parent whose thread had them blocked
    starts a process deaf to the stop its handlers are for: so started, ``simulate``
    killed with SIGTERM wrote its whole hour of bag and ended 0, and the node ran on
    until SIGKILL. One sent while they were blocked arrives here: its handler runs.
    """
    signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)


def give_back(taken: tuple | None) -> None:
    """Restore the mask and the handlers :func:`take` returned (nothing for None)."""
    if taken is None:
        return
    handlers, mask = taken
    signal.pthread_sigmask(signal.SIG_SETMASK, mask)
    for sig, handler in handlers.items():
        signal.signal(sig, handler)
