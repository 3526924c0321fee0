"""Silence what C code prints on the process's stdout and stderr for the length of a block (file descriptors 1
and 2): pybullet prints its build time and 'argv[0]=' there, which a node's output should not carry."""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys

_LIBC = ctypes.CDLL(None)


@contextlib.contextmanager
def quiet_c_stdout(descriptors: tuple[int, ...] = (1, 2)):
    """Send the descriptors to /dev/null inside the block (Python's streams are flushed first, C's at the end)."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(fd) for fd in descriptors]
    try:
        with open(os.devnull, 'w') as devnull:
            for fd in descriptors:
                os.dup2(devnull.fileno(), fd)
            try:
                yield
            finally:
                _LIBC.fflush(None)  # C's stdout is block-buffered into a pipe: empty it while it goes nowhere
                for fd, copy in zip(descriptors, saved):
                    os.dup2(copy, fd)
    finally:
        for copy in saved:
            os.close(copy)
