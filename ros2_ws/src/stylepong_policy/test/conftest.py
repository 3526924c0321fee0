"""Shared test helpers of stylepong_policy's tests are plain modules beside them (ppo_toy_task, json_text,
synthetic_reference).

The suite runs in pytest's importlib mode (test files of different packages share basenames), which
puts no test folder on sys.path; this one is added so the tests can `import ppo_toy_task`.
"""

import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
