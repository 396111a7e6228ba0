"""mechanism demo: the whole tool on the shipped sewing machine (what `make demo` runs)."""

ORDER = 5


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "demo",
        help="run everything on the shipped sewing machine and write OUT/index.html",
        description=(
            "Convert the shipped CAD export, inspect the needle motion, simulate the thesis's Table 2, a "
            "voltage-step run and sewing 12 layers, probe the crank pin and needle bar, check the needle's "
            "clearances (and a mistimed hook), render the 3-D animation, diagnose a bench recording with a "
            "concealed effect and simulate the stepper thread cut. Everything lands in OUT with an index.html."
        ),
    )
    parser.add_argument("--out", default="out", metavar="DIR", help="output folder, replaced as a whole (default out)")
    parser.set_defaults(handler=run)


def run(args) -> int:
    from mechanism.demo import run as demo

    demo(args.out)
    return 0
