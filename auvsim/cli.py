"""``auvsim`` command line: a thin shell that parses, builds a config and calls the library."""

from __future__ import annotations

import argparse
import sys

from .config import SCENARIOS, Config, MissionConfig, ScenarioConfig, VehicleConfig
from .errors import AuvsimError


class _Parser(argparse.ArgumentParser):
    """Reports a usage error on one line and exits with status 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message}\n")


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="auvsim", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    gen = sub.add_parser(
        "generate", help="simulate a mission and write an HDF5 dataset",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    gen.add_argument("--scenario", default="straight", help=f"one of: {', '.join(SCENARIOS)}")
    gen.add_argument("--speed", type=float, default=2.0, help="surge speed to hold, m/s")
    gen.add_argument("--heading-deg", type=float, default=0.0, help="heading, deg from north")
    gen.add_argument("--depth", type=float, default=20.0, help="depth to hold, m")
    gen.add_argument("--duration", type=float, default=600.0, help="mission length, s")
    gen.add_argument("--seed", type=int, default=0, help="seed of the random streams")
    gen.add_argument("--vehicle", default="auv",
                     help="auv (A18-D class), remus100, or a path to an MJCF model")
    gen.add_argument("--out", required=True, help="HDF5 file to write")
    gen.add_argument("--compression", choices=("lzf", "gzip"), default="lzf",
                     help="lzf is fast; gzip is read by every HDF5 tool without a plugin")
    gen.add_argument("--quiet", action="store_true", help="no progress bar")
    return parser


def _generate(args: argparse.Namespace) -> None:
    from .generate import generate  # numba compilation only for the commands that need it

    scenario = ScenarioConfig(name=args.scenario, speed=args.speed,
                              heading_deg=args.heading_deg, depth=args.depth,
                              duration=args.duration)
    config = Config(vehicle=VehicleConfig(model=args.vehicle),
                    missions=(MissionConfig(name="mission_000", scenario=scenario,
                                            seed=args.seed),),
                    compression=args.compression)
    summary = generate(config, args.out, progress=not args.quiet)
    print(f"wrote {args.out}: {summary['missions']} mission(s), {summary['simulated_s']:g} s "
          f"simulated in {summary['wall_s']:.1f} s "
          f"({summary['simulated_s'] / summary['wall_s']:.0f}x real time)")


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        {"generate": _generate}[args.command](args)
    except AuvsimError as e:
        print(f"auvsim: error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
