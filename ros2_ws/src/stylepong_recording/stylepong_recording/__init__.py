"""Recording demonstrations: the recorder node, crash-safe rosbag2 clip writing, bag recovery and the bag layout."""
