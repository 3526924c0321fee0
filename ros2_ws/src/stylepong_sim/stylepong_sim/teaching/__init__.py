"""The virtual teacher without ROS: a hand dragging the paddle through a stroke, and the named stroke styles."""
