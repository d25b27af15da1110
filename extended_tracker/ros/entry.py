"""
The ``tracker_node`` executable. It takes SIGINT and SIGTERM before anything heavy is
imported (rclpy, numpy, scipy: half a second here), so a stop asked for during start-up
ends the process quietly with status 0, as one asked for later does, instead of a
``KeyboardInterrupt`` traceback from an import or a kill by SIGTERM.
"""

import threading

from .. import stopping


def take_signals(stop: threading.Event) -> tuple:
    """Make SIGINT and SIGTERM set ``stop``, unblocked in this thread even when the
    process was started with them blocked (:func:`stopping.unblock`); returns what
    they had, for :func:`stopping.give_back`."""
    taken = stopping.take(lambda *_: stop.set())
    stopping.unblock()
    return taken


def main(args=None) -> None:
    stop = threading.Event()
    previous = take_signals(stop)
    try:
        from .node import main as run_node

        run_node(args, stop=stop)
    finally:
        stopping.give_back(previous)
