"""The one UR5 + table-tennis paddle model, loaded by Pinocchio and MuJoCo alike."""
