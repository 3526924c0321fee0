"""Where this package's sources lie in the repository.

`make setup` builds with --symlink-install, so a module's resolved `__file__` is its source file and the
checkout's folders are found from here. The shipping and experiment commands write into the checkout
(`models/`, `results/`), never into the install tree, which the next build replaces."""

import pathlib

PACKAGE_SOURCE = pathlib.Path(__file__).resolve().parents[1]  # ros2_ws/src/stylepong_policy
REPOSITORY = PACKAGE_SOURCE.parents[2]
MODELS = PACKAGE_SOURCE / 'models'
CONFIG = PACKAGE_SOURCE / 'config'
RESULTS = REPOSITORY / 'results'
SHIPPED_BAGS = REPOSITORY / 'ros2_ws' / 'bags'
