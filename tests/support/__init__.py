"""Helpers shared by the tests (fixtures that are not pytest fixtures)."""
