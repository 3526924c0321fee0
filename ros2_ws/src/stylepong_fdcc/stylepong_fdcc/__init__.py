"""Forward Dynamics Compliance Control drag teaching, crash-safe clip recorder and bag recovery."""
