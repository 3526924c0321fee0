"""MuJoCo UR5 table-tennis cell standing in for the hardware, and what surrounds it.

World spec, referee, virtual teacher, batched training world.
"""
