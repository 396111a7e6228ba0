"""Options of the verbs that run a batch (``mechanism.batch``): workers, backend, Ray cluster."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from mechanism.batch.runner import Backend


def backend_from_args(args) -> Backend:
    """``--backend`` as the API's :data:`~mechanism.batch.runner.Backend`."""
    from mechanism.batch.runner import BACKENDS
    from mechanism.cli._choices import chosen

    return chosen(args.backend, BACKENDS, "--backend")


def add_batch_arguments(parser, what: str) -> None:
    """--workers, --backend, --ray-address for a verb whose batch items are ``what``."""
    from mechanism.batch import MAX_WORKERS
    from mechanism.files.limits import number

    parser.add_argument(
        "--workers",
        type=number(1, MAX_WORKERS, integer=True),
        default=1,
        metavar="K",
        help=f"parallel worker processes for {what} (default 1; with --backend ray and no cluster: "
        "the CPUs of the local Ray instance)",
    )
    parser.add_argument(
        "--backend",
        choices=["local", "ray"],
        default="local",
        help="where the batch runs: local processes, or Ray (pip install 'mechanism[ray]'): the cluster "
        "at --ray-address, else a private local instance started and stopped for this run",
    )
    parser.add_argument(
        "--ray-address",
        metavar="ADDR",
        help="a running Ray cluster to use with --backend ray, e.g. 10.0.0.5:6379 (from `ray start "
        "--head`; default: the RAY_ADDRESS environment variable); its workers need mechanism installed",
    )


def check_batch_arguments(args, batch: bool, what: str) -> None:
    """--workers/--ray-address only make sense for a batch; --ray-address only with Ray."""
    from mechanism.errors import UserError

    if not batch and (args.workers != 1 or args.backend != "local" or args.ray_address):
        raise UserError(f"--workers, --backend and --ray-address apply to {what}")
    if args.ray_address and args.backend != "ray":
        raise UserError("--ray-address needs --backend ray")
