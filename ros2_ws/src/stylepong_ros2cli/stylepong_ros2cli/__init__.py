"""The `ros2` command of an install without ros2cli (the ROS 2 Jazzy PyPI wheels): `helper.main`."""
