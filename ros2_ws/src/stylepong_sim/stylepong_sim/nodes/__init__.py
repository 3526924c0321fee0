"""What `ros2 run stylepong_sim ...` starts: the cells' node, the virtual teacher's, the robot state publisher,
rally_eval and cell_calibration; each module is thin wiring around the plain modules beside this package."""
