"""
A stop asked for by SIGTERM while an ``extended-tracker`` command runs.

The command line's handler raises :class:`Terminated` in the main thread, so cleanups run
as they do for Ctrl-C: a half-written bag's staging folder is removed. An exception that
a signal handler raises can be lost, though: C code running at that moment may clear it.
An extension module's import did (numpy.random's, the first thing a simulation does):
about one SIGTERM in 30 sent just after ``simulate`` started its bag was dropped there,
and the command wrote its whole bag and ended with status 0.

So the handler also sets a flag that stays set, and the places that decide a command's
outcome look at it with :func:`check`: every scan of a bag being written or replayed,
the move of a finished bag into place (:func:`bagio.staged_bag`), and the end of the
command. Outside the command line nothing sets the flag and :func:`check` does nothing.
"""

from __future__ import annotations

import threading


class Terminated(BaseException):
    """SIGTERM arrived: raised in the main thread so cleanups run, as for Ctrl-C."""


_requested = threading.Event()


def on_sigterm(signum, frame):
    """The SIGTERM handler: remember the request, then raise :class:`Terminated`."""
    _requested.set()
    raise Terminated


def check() -> None:
    """Raise :class:`Terminated` if a SIGTERM arrived (even one whose exception was lost)."""
    if _requested.is_set():
        raise Terminated


def requested() -> bool:
    """Whether a SIGTERM arrived since :func:`reset`."""
    return _requested.is_set()


def reset() -> None:
    """Forget an earlier request (a new command starts)."""
    _requested.clear()
