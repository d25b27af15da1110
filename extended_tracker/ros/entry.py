"""
The ``tracker_node`` executable. It takes SIGINT and SIGTERM before anything heavy is
imported (rclpy, numpy, scipy: half a second here), so a stop asked for during start-up
ends the process quietly with status 0, as one asked for later does, instead of a
``KeyboardInterrupt`` traceback from an import or a kill by SIGTERM.
"""

import signal
import threading

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def take_signals(stop: threading.Event) -> dict:
    """Make SIGINT and SIGTERM set ``stop``; returns the handlers they had."""
    return {sig: signal.signal(sig, lambda *_: stop.set()) for sig in STOP_SIGNALS}


def give_back(previous: dict) -> None:
    """Restore the handlers :func:`take_signals` replaced."""
    for sig, handler in previous.items():
        signal.signal(sig, handler)


def main(args=None) -> None:
    stop = threading.Event()
    previous = take_signals(stop)
    try:
        from .node import main as run_node

        run_node(args, stop=stop)
    finally:
        give_back(previous)
