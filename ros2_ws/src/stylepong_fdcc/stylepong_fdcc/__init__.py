"""Forward Dynamics Compliance Control drag teaching."""
