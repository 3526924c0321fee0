"""MuJoCo UR5 table-tennis cell standing in for the hardware, world spec, referee, virtual teacher, batched training world."""
