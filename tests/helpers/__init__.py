"""Helpers shared by the tests and bench/ (fixtures that are not pytest fixtures): hand-written CAD
exports, small mechanisms, truth models, fault injection. Imported as ``tests.helpers.<module>``."""
