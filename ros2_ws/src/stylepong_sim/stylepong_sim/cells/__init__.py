"""The simulated cells without ROS: the MuJoCo cell and the PyBullet cell on one engine-free base, and what
they are made of (the scene, the analytic ball contacts, the actuator models, the sensors and the tracker,
video) and the checks run on them."""
