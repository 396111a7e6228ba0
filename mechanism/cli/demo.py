"""mechanism demo: the whole tool on every shipped machine (what `make demo` runs)."""

ORDER = 5


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "demo",
        help="run everything on every shipped machine and write OUT/index.html",
        description=(
            "For each shipped machine (or the one --machine names): convert its CAD export, inspect the tool "
            "motion, simulate it against its shipped steady-speed measurements (the Sapphire 870: the thesis's "
            "Table 2, cold and warm), a voltage-step run and a sewing run, probe and check clearances as its "
            "description says (with a faulty design variant), render the 3-D animation and diagnose a virtual "
            "bench recording with a concealed effect. Everything lands in OUT with an index.html."
        ),
    )
    parser.add_argument(
        "--out",
        default="out",
        metavar="DIR",
        help="output folder, replaced as a whole (default out)",
    )
    parser.add_argument(
        "--machine",
        action="append",
        metavar="NAME",
        help="only this shipped machine (repeatable; default: all of them)",
    )
    parser.set_defaults(handler=run, output_dirs=("out",))


def run(args) -> int:
    from mechanism.demo import run as demo

    demo(args.out, args.machine)
    return 0
