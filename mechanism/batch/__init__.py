"""Batch work: one function over many items, on local worker processes or a Ray cluster."""

from mechanism.batch.runner import (
    BACKENDS,
    MAX_WORKERS,
    BatchLost,
    check_options,
    ray_address_from,
    run_batch,
)

__all__ = ["BACKENDS", "MAX_WORKERS", "BatchLost", "check_options", "ray_address_from", "run_batch"]
