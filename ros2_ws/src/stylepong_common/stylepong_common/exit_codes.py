"""The exit statuses that StylePong's nodes and command-line tools share (no rclpy), defined once so that
scripts and tests that check a status (tools/*.sh, tests/test_bad_parameters.py) read the same numbers the
programs return."""

# The program stopped on its own before it was done (a node whose ROS context was shut down under it).
EXIT_STOPPED = 1
# A bad parameter or command-line option: one line on stderr naming it (argparse's own usage-error code).
EXIT_CONFIG_ERROR = 2
# The exit status of a program ended by SIGINT, as a shell reports it (128 + 2).
EXIT_INTERRUPTED = 130
