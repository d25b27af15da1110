"""Start a command as a parent whose thread had SIGINT and SIGTERM blocked would: a
blocked signal mask is inherited across exec (imported by the tests, not a test)."""

import sys

_BLOCK_THEN_EXEC = ('import os, signal, sys; '
                    'signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM}); '
                    'os.execv(sys.argv[1], sys.argv[1:])')


def stops_blocked(argv: list) -> list:
    """``argv`` run with SIGINT and SIGTERM blocked from its first instruction."""
    return [sys.executable, '-c', _BLOCK_THEN_EXEC, *argv]
