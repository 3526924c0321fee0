"""Helpers that only the tests use (shipped so that the system tests in tests/ can import them)."""
