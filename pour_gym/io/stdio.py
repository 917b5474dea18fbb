"""Where C libraries' output goes: file descriptor 1 redirected for a while.

The command line prints exactly one JSON document on stdout with ``--json``, but pybullet
writes ``argv[0]=`` there on every connection and V-HACD reports its progress there, from C,
past Python's ``sys.stdout``. Redirecting the descriptor catches both.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator


@contextlib.contextmanager
def redirect_stdout_fd(target: int | None = None) -> Iterator[None]:
    """Send what is written to file descriptor 1 elsewhere for the duration.

    Args:
        target: a file descriptor to send it to (2 for stderr); ``None`` discards it.
    """
    sys.stdout.flush()
    saved = os.dup(1)
    sink = os.open(os.devnull, os.O_WRONLY) if target is None else None
    try:
        os.dup2(target if sink is None else sink, 1)
        yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)
        if sink is not None:
            os.close(sink)
