"""``mechanism cache``: where the cache of converted exports and compiled kernels is, and emptying it."""

from __future__ import annotations

ORDER = 90


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "cache",
        help="show or empty the cache of converted CAD exports and compiled kernels",
        description=(
            "mechanism converts a CAD export named as a machine's model once and compiles its C kernels once, "
            "into a cache: $MECHANISM_CACHE/mechanism, else $XDG_CACHE_HOME/mechanism, else ~/.cache/mechanism. "
            "Each entry is checked against its content hashes before use (a damaged one is rebuilt with a warning); "
            "the cache is bounded by $MECHANISM_CACHE_MAX_MB (default 1024 MiB), the least recently used entries "
            "going first. 'info' shows it, 'clear' empties it (everything is rebuilt on demand)."
        ),
        epilog="example: mechanism cache clear",
    )
    parser.add_argument(
        "action",
        choices=("info", "clear"),
        help="info: location and size; clear: remove every entry",
    )
    parser.set_defaults(handler=run)


def run(args) -> int:
    from mechanism.files.cache import cache_info, clear_cache

    if args.action == "clear":
        before = clear_cache()
        print(
            f"cleared the cache {before.root}: removed {before.entries} entries, {before.bytes / 2**20:.1f} MiB"
        )
    else:
        print(cache_info().describe())
    return 0
