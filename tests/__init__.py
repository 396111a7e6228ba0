"""The tests as a package, so tests, their subprocesses and bench/ all import helpers as ``tests.helpers.<module>``
with the repository root on the path."""
