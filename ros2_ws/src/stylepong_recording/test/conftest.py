"""Shared test helpers of stylepong_recording's tests are plain modules beside them (offline_clips).

The suite runs in pytest's importlib mode (test files of different packages share basenames), which
puts no test folder on sys.path; this one is added so the tests can `import offline_clips`.
"""

import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
