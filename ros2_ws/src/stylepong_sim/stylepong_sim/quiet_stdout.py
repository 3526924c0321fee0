"""Silence what C code prints on the process's stdout for the length of a block (file descriptor 1)."""
from __future__ import annotations

import contextlib
import os
import sys


@contextlib.contextmanager
def quiet_c_stdout():
    """Send file descriptor 1 to /dev/null inside the block (Python's buffered stdout is flushed first)."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, 'w') as devnull:
            os.dup2(devnull.fileno(), 1)
            try:
                yield
            finally:
                os.dup2(saved, 1)
    finally:
        os.close(saved)
