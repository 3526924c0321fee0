"""The deployable side of a trained actor: its observation/action contract, the checks an exported actor must
pass, and the 60 Hz player node. Imports neither torch (but for the TorchScript backend) nor the simulator."""
