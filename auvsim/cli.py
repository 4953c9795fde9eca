"""``auvsim`` command line: a thin shell that parses, builds a config and calls the library."""

from __future__ import annotations

import argparse
import dataclasses
import errno
import math
import os
import re
import signal
import sys
import threading
from pathlib import Path

from auvsim.cli_support import exit_with, run_command
from auvsim.config import SCENARIOS, Config, ScenarioConfig, load_config
from auvsim.errors import ConfigError, OneLineErrorParser

DESCRIPTION = """Simulate a torpedo-shaped AUV with MuJoCo and write what its DVL, IMU and
depth sensor measure, beside the true motion, as HDF5 datasets."""
EXAMPLES = """examples:
  auvsim generate --duration 600 --seed 1 --out demo/straight.h5
  auvsim generate --preset maneuvers --out datasets/maneuvers.h5
  auvsim inspect demo/straight.h5
  auvsim plot demo/straight.h5
  auvsim import DIR --format akit --out snapir.h5
  auvsim check-log snapir.h5 --apply snapir-checked.h5
  auvsim export demo/straight.h5 --to pd0 --out demo/straight.pd0
  auvsim export demo/straight.h5 --to mcap --out demo/straight.mcap

Each command has its own --help."""

DATASET_HELP = "a dataset: an .h5 file, or a sharded dataset's folder (or its index.h5)"

# The flag each library argument is given on this command line (errors name arguments).
FLAGS = {"out": "--out", "seed": "--seed", "missions": "--mission", "config": "--config",
         "workers": "--workers", "shards": "--shards", "cluster": "--cluster",
         "description": "--description", "format": "--format", "sources": "SOURCE",
         "mission": "--mission", "coordinates": "--coordinates", "dataset": "DATASET",
         "topics": "--topics", "source": "DATASET", "apply": "--apply"}

_SCENARIO_FLAGS = {  # flag -> (ScenarioConfig field, help)
    "scenario": ("name", f"one of: {', '.join(SCENARIOS)}"),
    "speed": ("speed", "surge speed to hold, m/s"),
    "heading_deg": ("heading_deg", "heading to hold, deg from north"),
    "depth": ("depth", "depth to hold, m"),
    "duration": ("duration", "mission length, s"),
}


def _parser() -> argparse.ArgumentParser:
    parser = OneLineErrorParser(prog="auvsim", description=DESCRIPTION, epilog=EXAMPLES,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True,
                                parser_class=OneLineErrorParser)
    gen = sub.add_parser(
        "generate", help="simulate missions and write an HDF5 dataset",
        description="Simulate missions and write an HDF5 dataset. Without --preset or "
        "--config, one mission with the 'navigator' preset's sensors. Scenario options "
        "given with a preset or config override every mission's.")
    source = gen.add_mutually_exclusive_group()
    source.add_argument("--preset", metavar="NAME",
                        help="a named config ('auvsim presets' lists them; default: "
                        "navigator)")
    source.add_argument("--config", type=Path, metavar="FILE",
                        help="a TOML file with the full config")
    defaults = ScenarioConfig()
    for flag, (name, text) in _SCENARIO_FLAGS.items():
        kind = str if flag == "scenario" else float
        default = getattr(defaults, name)
        gen.add_argument(f"--{flag.replace('_', '-')}", dest=flag, type=kind,
                         metavar="NAME" if flag == "scenario" else "X",
                         help=f"{text} (default: {default if kind is str else f'{default:g}'})")
    gen.add_argument("--option", action="append", type=_option, metavar="NAME=X",
                     dest="options", help="a scenario option, any number of times "
                     "(--scenario zigzag --option rudder_deg=20); each scenario's are in "
                     "the guide's table of scenarios (default: the scenario's)")
    gen.add_argument("--seed", type=int, metavar="N",
                     help="seed of the first mission; the others follow, N+1, N+2, ... (so "
                     "two datasets' seeds closer than their mission count share missions' "
                     "draws; default: the preset's, 0 otherwise)")
    gen.add_argument("--vehicle", metavar="NAME",
                     help="auv (A18-D class), remus100, or a MuJoCo model file (default: the "
                     "preset's, auv); the preset's sensor sites and turbulence follow it")
    gen.add_argument("--workers", type=int, metavar="N",
                     help="worker processes, each running two missions at a time "
                     "(default: one per two cores)")
    gen.add_argument("--compression", choices=("lzf", "gzip"),
                     help="lzf is fast; gzip is read by every HDF5 tool (default: lzf)")
    gen.add_argument("--cluster", metavar="ADDRESS",
                     help="run the missions on a Dask cluster: local:N (N worker processes "
                     "here) or a scheduler's address, host:port (needs auvsim[cluster]; "
                     "--out must be on storage every worker reaches)")
    gen.add_argument("--shards", type=int, metavar="N",
                     help="write a sharded dataset into the folder --out, N missions per "
                     "shard file, with an index that reads as one dataset (default 1 when "
                     "--out ends in /); running again finishes or checks it")
    gen.add_argument("--out", required=True, type=_nameable, metavar="PATH",
                     help="HDF5 file to write, or a folder ending in / for a sharded dataset")
    gen.add_argument("--quiet", action="store_true", help="no progress bar")
    sub.add_parser("presets", help="list the named configs",
                   description="List the named configs that generate --preset takes, with "
                   "what each simulates.")
    inspect = sub.add_parser(
        "inspect", help="describe a dataset file",
        description="Describe a dataset: its missions, their sensors and realised errors, "
        "and the fields it holds. Every value is read and checked, so a damaged file is "
        "refused.")
    inspect.add_argument("file", type=Path,
                         help=DATASET_HELP)
    imp = sub.add_parser(
        "import-velocity",
        help="make a dataset from recorded DVL velocities (import --format velocity)",
        description="Take recorded DVL velocities as the truth and synthesise the beams a "
        "DVL under test would measure, with a preset's DVL error model, as the BeamsNet "
        "paper's sea experiment did. Each file becomes one mission (named by the file) "
        "with no IMU, so only estimators that do without an IMU can use it.")
    imp.add_argument("files", type=Path, nargs="+", metavar="FILE",
                     help=".npy of shape (3, N), or .csv of N rows vx,vy,vz; m/s in the DVL's "
                     "frame")
    _velocity_options(imp)
    imp.add_argument("--compression", choices=("lzf", "gzip"), default="lzf",
                     help="lzf is fast; gzip is read by every HDF5 tool (default: lzf)")
    imp.add_argument("--out", type=_file_out, required=True, metavar="FILE",
                     help="HDF5 file to write")
    _import_parser(sub)
    _check_log_parser(sub)
    _export_parser(sub)
    _serve_parser(sub)
    plot = sub.add_parser(
        "plot", help="draw each mission of a dataset to PNG",
        description="Draw each mission of a dataset to a PNG: track, depth over the "
        "seafloor, speed over ground and through the water, attitude, DVL velocity, the "
        "beams' status and, where the file has them, the current and the DVL's error "
        "velocity.")
    plot.add_argument("file", type=Path,
                      help=DATASET_HELP)
    plot.add_argument("--mission", action="append", dest="missions", metavar="NAME",
                      help="draw this mission only (repeatable; default: all)")
    plot.add_argument("--out", type=Path, metavar="DIR",
                      help="folder for the PNGs, <file>_<mission>.png (default: beside the "
                      "file)")
    return parser


# ---- auvsim import: recorded logs (auvsim.data.recorded) and velocity streams ----------


# import-velocity's options, and import's for --format velocity (None there until then).
_VELOCITY_DEFAULTS = {"rate": 1.0, "preset": "paper-sim", "noise_std": None, "seed": 0}


def _velocity_options(parser: argparse.ArgumentParser, *, only: str = "") -> None:
    """--rate, --preset, --noise-std and --seed of a velocity import. With ``only`` (a
    help prefix: the command takes other formats too) they default to None, so that
    ``_import`` can tell one given with another format."""
    default = dict.fromkeys(_VELOCITY_DEFAULTS) if only else _VELOCITY_DEFAULTS
    parser.add_argument("--rate", type=float, default=default["rate"], metavar="HZ",
                        help=f"{only}ping rate of the files, Hz (default: 1)")
    parser.add_argument("--preset", default=default["preset"], metavar="NAME",
                        help=f"{only}whose DVL (beam angle, scale factor, bias, noise) to "
                        "apply (default: paper-sim)")
    parser.add_argument("--noise-std", type=float, default=default["noise_std"], metavar="X",
                        help=f"{only}beam noise std, m/s (default: the preset's)")
    parser.add_argument("--seed", type=int, default=default["seed"], metavar="N",
                        help=f"{only}seed of the first file's errors and noise; the others "
                        "follow (default: 0)")


def _import_parser(sub) -> None:
    imp = sub.add_parser(
        "import", help="make a dataset from a vehicle's recorded logs",
        description="Make a dataset of recorded missions from a vehicle's logs: IMU, DVL, "
        "depth and a reference navigation solution, each on its own clock, nothing "
        "resampled. --format akit reads the A-KIT layout (TrajectoryK/{IMU,DVL,GT}_"
        "trajectoryK.csv, one mission per segment); --format csv reads a folder of CSV "
        "files that a log description (TOML) explains; --format pd0 reads a Teledyne RDI "
        "Workhorse DVL's PD0 files (a mission of the DVL alone each; the description gives "
        "the origin and the instrument's figures); --format velocity is import-velocity "
        "(recorded DVL velocities taken as the truth, beams synthesised).")
    imp.add_argument("sources", type=Path, nargs="+", metavar="SOURCE",
                     help="akit: the A-KIT folder or a TrajectoryK folder; csv: a log's "
                     "folder; pd0: PD0 files; velocity: .npy (3, N) or .csv (N rows "
                     "vx,vy,vz) files")
    imp.add_argument("--format", choices=("akit", "csv", "pd0", "velocity"), required=True,
                     help="the logs' layout (required; no default)")
    imp.add_argument("--description", type=Path, metavar="LOG.toml",
                     help="the log description (csv and pd0 only; default: none, required "
                     "there)")
    _velocity_options(imp, only="velocity only: ")
    imp.add_argument("--compression", choices=("lzf", "gzip"), default="lzf",
                     help="lzf is fast; gzip is read by every HDF5 tool (default: lzf)")
    imp.add_argument("--out", type=_file_out, required=True, metavar="FILE",
                     help="HDF5 file to write")


def _import(args: argparse.Namespace) -> None:
    from auvsim.data.writer import check_output_path

    if args.format == "velocity":
        if args.description is not None:
            raise ConfigError("--description: only for --format csv and pd0")
        for key, default in _VELOCITY_DEFAULTS.items():
            if getattr(args, key) is None:
                setattr(args, key, default)
        args.files = args.sources
        _import_velocity(args)
        return
    given = [key for key in _VELOCITY_DEFAULTS if getattr(args, key) is not None]
    if given:
        raise ConfigError(f"--{given[0].replace('_', '-')}: only for --format velocity")
    check_output_path(args.out)  # before the logs are read (velocity: its own command's)
    if args.format == "pd0":
        _import_pd0(args)
        return
    from auvsim.data.recorded import import_logs

    summary = import_logs(args.sources, args.out, format=args.format,
                          description=args.description, compression=args.compression)
    missions = "; ".join(
        f"{name} (" + ", ".join(f"{g} {rows} at {rate:.4g} Hz"
                                for g, (rows, rate) in groups.items()) + ")"
        for name, groups in summary.items())
    print(f"wrote {args.out}: {missions}")


def _import_pd0(args: argparse.Namespace) -> None:
    from auvsim.data.pd0 import import_pd0

    summary = import_pd0(args.sources, args.out, description=args.description,
                         compression=args.compression)
    missions = "; ".join(
        f"{name} (dvl {s['dvl'][0]} pings at {s['dvl'][1]:.4g} Hz, {s['coordinates']} "
        f"coordinates; skipped: {s['bad_checksum']} ensemble(s) failing their checksum, "
        f"{s['truncated']} cut off)" for name, s in summary.items())
    print(f"wrote {args.out}: {missions}")


# ---- auvsim check-log: what a recorded log does not document (auvsim.data.checklog) ----


def _check_log_parser(sub) -> None:
    check = sub.add_parser(
        "check-log", help="find a recorded log's IMU axes, clocks, lever arms and more",
        description="Find what a recorded log does not document, from its data, against "
        "its reference: the IMU's axis convention, each stream's clock offset and rate "
        "error, the IMU's and the DVL's positions from the reference point, gravity, and "
        "the DVL's scale and mounting; each with its evidence and a confidence. --apply "
        "writes a corrected copy of the dataset.")
    check.add_argument("file", type=Path, help="a dataset of recorded missions (auvsim "
                       "import)")
    check.add_argument("--mission", action="append", dest="missions", metavar="NAME",
                       help="check this mission only (repeatable; default: all)")
    check.add_argument("--json", action="store_true",
                       help="print the findings as JSON instead of tables")
    check.add_argument("--apply", type=_file_out, metavar="OUT.h5",
                       help="write the dataset corrected by the findings to this file "
                       "(default: none)")
    check.add_argument("--accept-low", action="store_true",
                       help="with --apply, write corrections whose finding is of low "
                       "confidence too (default: refuse them, writing nothing)")


def _check_log(args: argparse.Namespace) -> None:
    from tqdm import tqdm

    from auvsim.data.checklog import apply, check_file, to_json
    from auvsim.data.reader import open_dataset
    from auvsim.data.writer import check_output_path

    if args.apply is not None and args.apply.resolve() == args.file.resolve():
        raise ConfigError(f"--apply: {str(args.apply)!r} is the log itself; expected another "
                          "file (the log stays as recorded)")
    if args.apply is not None:  # refused now, not after the checks' work
        check_output_path(args.apply, "apply")
    with open_dataset(args.file) as ds:  # refused in one line if it is no dataset
        in_file = len(ds.missions)
    total = len(args.missions) if args.missions else in_file
    # Each mission's table as soon as it is checked, under a bar (on a terminal) of the
    # missions: the first check of a session compiles its kernels, some 30 s.
    with tqdm(total=total, desc="checking", unit=" mission", disable=None, leave=False,
              file=sys.stderr) as bar:
        def done(report) -> None:
            if not args.json:
                bar.write(report.table() + "\n", file=sys.stdout)
            bar.update()
        reports = check_file(args.file, args.missions, each=done)
    if args.json:
        print(to_json(reports))
    if args.apply is not None:
        said = apply(args.file, args.apply, reports, accept_low=args.accept_low)
        if not args.json:
            others = in_file - len(reports)
            print(f"wrote {args.apply}: {', '.join(r.mission for r in reports)} corrected"
                  + (f", {others} other mission(s) as they were" if others > 0 else ""))
            for mission, changed in said.items():
                print(f"  {mission}: " + ("; ".join(changed) or "nothing to correct"))


# ---- auvsim export: a mission in another tool's format (auvsim.interop, auvsim.data.pd0) --


def _export_pd0(args: argparse.Namespace) -> None:
    from auvsim.data.pd0 import export_pd0

    done = export_pd0(args.dataset, args.out, mission=args.mission,
                      coordinates=args.coordinates or "beam")
    print(f"wrote {args.out}: mission {done['mission']}, {done['ensembles']} PD0 ensembles "
          f"({done['bytes']} bytes), bottom track in {done['coordinates']} coordinates")


def _export_mcap(args: argparse.Namespace) -> None:
    from auvsim.data.recorded import load_toml, read_description
    from auvsim.interop.ros2 import export_mcap

    topics = None
    if args.topics is not None:
        text = read_description(args.topics, argument="topics")
        topics = load_toml(text, where=f"--topics {str(args.topics)!r}")
    counts = export_mcap(args.dataset, args.out, mission=args.mission, topics=topics,
                         compression=args.compression or "zstd", progress=True)
    print(f"wrote {args.out}: " + ", ".join(f"{topic} {n}" for topic, n in counts.items()))


# --to FORMAT -> the function that writes it; the options only one format takes.
_EXPORTERS = {"mcap": _export_mcap, "pd0": _export_pd0}
_EXPORT_ONLY = {"coordinates": "pd0", "topics": "mcap", "compression": "mcap"}


def _export_parser(sub) -> None:
    export = sub.add_parser(
        "export", help="write a mission in a format other tools read",
        description="Write one mission of a dataset in another tool's format. --to mcap: a "
        "ROS 2 bag in MCAP (IMU, DVL, depth, the truth or a recorded mission's reference as "
        "odometry, the mountings on /tf_static), message definitions embedded, readable "
        "without ROS. --to pd0: the DVL's pings as a Teledyne RDI Workhorse DVL's PD0 "
        "ensembles (header, fixed and variable leaders, bottom track with checksums), in "
        "beam or instrument coordinates. Needs auvsim[io].")
    export.add_argument("dataset", type=Path, metavar="DATASET",
                        help=DATASET_HELP)
    export.add_argument("--to", choices=sorted(_EXPORTERS), required=True,
                        help="the format (required; no default)")
    export.add_argument("--out", type=Path, required=True, metavar="FILE",
                        help="the file to write (its folder made if missing)")
    export.add_argument("--mission", metavar="NAME",
                        help="the mission to write (default: the dataset's only one)")
    export.add_argument("--topics", type=Path, metavar="FILE.toml",
                        help="mcap only: topic names replacing the defaults, key = \"/name\" "
                        "per line; keys: imu, dvl, depth, truth, reference, tf_static "
                        "(default: /imu/data, /dvl/data, /depth/pose, /truth/odometry, "
                        "/reference/odometry, /tf_static)")
    export.add_argument("--compression", choices=("zstd", "lz4", "none"),
                        help="mcap only: the chunks' compression (default: zstd)")
    export.add_argument("--coordinates", choices=("beam", "instrument"),
                        help="pd0 only: the bottom-track velocities' coordinates (default: "
                        "beam)")


def _export(args: argparse.Namespace) -> None:
    for key, only in _EXPORT_ONLY.items():
        if getattr(args, key, None) is not None and args.to != only:
            raise ConfigError(f"--{key}: only for --to {only}")
    _EXPORTERS[args.to](args)


# ---- auvsim serve: a mission played as a DVL on the network (auvsim.interop.a50) ------

FLAGS.update({"mission": "--mission", "host": "--host", "port": "--port", "speed": "--speed"})


def _serve_parser(sub) -> None:
    serve = sub.add_parser(
        "serve", help="play a mission as a Water Linked DVL A50 on TCP",
        description="Play a simulated mission's DVL as a Water Linked DVL A50 plays on its "
        "network: its TCP JSON API (json_v3.1), a velocity-and-transducer report and a "
        "dead-reckoning report per ping, one JSON object per line, to every client; it "
        "answers get_config, set_config, reset_dead_reckoning and calibrate_gyro. It stops "
        "after the mission's last ping (unless --loop), or on Ctrl-C or SIGTERM, and says "
        "what it served.")
    serve.add_argument("file", type=Path, help="a dataset of simulated missions")
    serve.add_argument("--dvl", choices=("a50",), required=True,
                       help="the instrument to play (required; a50: Water Linked DVL A50)")
    serve.add_argument("--mission", metavar="NAME",
                       help="the mission to play (default: the dataset's only one)")
    serve.add_argument("--host", default="127.0.0.1",
                       help="address to listen on (default: 127.0.0.1, this machine only)")
    serve.add_argument("--port", type=int, default=16171,
                       help="TCP port (default: 16171, the A50's; 0: any free port)")
    serve.add_argument("--speed", type=float, default=1.0, metavar="X",
                       help="mission seconds per second (default: 1, real time)")
    serve.add_argument("--loop", action="store_true",
                       help="play the mission again from its start after its last ping")
    serve.add_argument("--wait-for-client", action="store_true",
                       help="start the mission's clock when the first client connects")


def _serve(args: argparse.Namespace) -> None:
    from auvsim.interop.a50 import serve

    def ready(host: str, port: int, pings) -> None:
        rate = 1e3 / float(pings.interval_ms[0])
        print(f"serving {pings.name} of {args.file} as a Water Linked DVL A50 (json_v3.1) on "
              f"{host}:{port}: {len(pings)} pings at {rate:g} Hz, {args.speed:g}x real time"
              f"{', looping' if args.loop else ''}"
              f"{', from the first client' if args.wait_for_client else ''}; Ctrl-C stops",
              flush=True)

    # Ctrl-C and SIGTERM are how a server is stopped: they end the play within 50 ms, and
    # the command says what it served and exits 0 (from another thread than the main one,
    # where no handler can be set, they stay an interrupt).
    stop = threading.Event()
    handlers = {}
    if threading.current_thread() is threading.main_thread():
        handlers = {signum: signal.signal(signum, lambda *_: stop.set())
                    for signum in (signal.SIGINT, signal.SIGTERM)}
    try:
        summary = serve(args.file, args.mission, host=args.host, port=args.port,
                        speed=args.speed, loop=args.loop,
                        wait_for_client=args.wait_for_client, ready=ready, stop=stop)
    finally:
        for signum, handler in handlers.items():
            signal.signal(signum, handler)
    print(f"served {summary['reports']} velocity reports of {summary['mission']} to "
          f"{summary['clients']} client(s)" + ("; stopped by a signal" if stop.is_set() else ""))


def _nameable(path: str) -> str:
    """A path the operating system can name (not empty; no component or whole too long for
    it)."""
    if not path.strip():
        raise argparse.ArgumentTypeError(f"{path!r}: empty; expected a path")
    try:
        os.stat(path)
    except OSError as e:
        if e.errno == errno.ENAMETOOLONG:
            raise argparse.ArgumentTypeError(f"{path[:80]!r}...: {e.strerror}") from None
    except ValueError as e:  # a NUL byte, from a caller of main() (a shell cannot pass one)
        raise argparse.ArgumentTypeError(f"{path[:80]!r}: {e}") from None
    return path


def _file_out(path: str) -> Path:
    """An output file's path: nameable, and not a folder's (a trailing /)."""
    from auvsim.data.files import names_folder

    if names_folder(_nameable(path)):
        raise argparse.ArgumentTypeError(f"{path!r} ends in /, a folder; expected the file "
                                         "to write")
    return Path(path)


def _option(text: str) -> tuple[str, float]:
    """``--option NAME=X``: a scenario option's name and number."""
    name, _, value = text.partition("=")
    try:
        number = float(value)  # "" (no "=") is no number either
    except ValueError:
        number = math.nan
    if not name.strip() or not math.isfinite(number):
        raise argparse.ArgumentTypeError(f"expected NAME=X, an option's name and a finite "
                                         f"number (rudder_deg=20), got {text!r}")
    return name.strip(), number


def _check_options_fit(options, flown: list[str], source: str) -> None:
    """Refuse an ``--option`` that some of the missions' manoeuvres take and others do not
    (each would have said only that the first one lacking it does not take it)."""
    from auvsim.physics.maneuvers import MANEUVERS

    flown = [n for n in dict.fromkeys(flown) if n in MANEUVERS]
    for key, _ in options:
        taking = [n for n in flown
                  if key in {f.name for f in dataclasses.fields(MANEUVERS[n].Options)}]
        if taking and len(taking) < len(flown):
            lacking = [n for n in flown if n not in taking]
            raise ConfigError(f"--option {key}: the missions of {source} fly different "
                              f"manoeuvres, and {', '.join(lacking)} take no such option "
                              f"(only {', '.join(taking)}); expected --scenario NAME with it, "
                              "or a config file (--config) with each mission's options")


def build_config(args: argparse.Namespace) -> Config:
    """The config a ``generate`` command line asks for."""
    from auvsim.runs.presets import DEFAULT_PRESET, preset, with_vehicle

    if args.config is not None:
        config = load_config(args.config)
    else:
        config = preset(args.preset or DEFAULT_PRESET)
    overrides = {name: getattr(args, flag) for flag, (name, _) in _SCENARIO_FLAGS.items()
                 if getattr(args, flag) is not None}
    source = (f"config {str(args.config)!r}" if args.config is not None
              else f"preset {args.preset or DEFAULT_PRESET!r}")
    for flag, (name, _) in _SCENARIO_FLAGS.items():
        # One value over missions that differ in it would leave them named for what they
        # no longer are (maneuvers' turning_circle flying a zigzag, paper-sim's speed_1 at 2).
        values = list(dict.fromkeys(getattr(m.scenario, name) for m in config.missions))
        if name not in overrides or len(values) == 1:
            continue
        option = f"--{flag.replace('_', '-')}"
        shown = ", ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in values)
        raise ConfigError(f"{option}: the missions of {source} differ in it ({shown}) and are "
                          f"named for that; expected it without {option}, or a config file "
                          "(--config) with the missions you want")
    _check_options_fit(args.options or (), [overrides.get("name", m.scenario.name)
                                            for m in config.missions], source)

    def scenario(old: ScenarioConfig) -> ScenarioConfig:
        fields = {**dataclasses.asdict(old), **overrides}
        if fields["name"] != old.name:
            fields["options"] = {}  # another manoeuvre: the old one's options do not apply
        fields["options"] = {**fields["options"], **dict(args.options or ())}
        return ScenarioConfig(**fields)

    missions = tuple(
        dataclasses.replace(m, scenario=scenario(m.scenario),
                            seed=m.seed if args.seed is None else args.seed + i)
        for i, m in enumerate(config.missions))
    changes: dict = {"missions": missions}
    if args.compression is not None:
        changes["compression"] = args.compression
    config = dataclasses.replace(config, **changes)
    return config if args.vehicle is None else with_vehicle(config, args.vehicle)


def _generate(args: argparse.Namespace) -> None:
    from auvsim.data.files import interrupts_held

    with interrupts_held():  # MuJoCo's extension init would swallow a Ctrl-C
        from auvsim.runs.generate import (
            generate,  # numba compilation only for the commands that need it
        )

    config = build_config(args)
    summary = generate(config, args.out, workers=args.workers, cluster=args.cluster,
                       shards=args.shards, progress=not args.quiet)
    # numba's cache did not have it (all of it on a first run; on a later one, the code
    # of a scenario not flown before): said where it happened, and not under --quiet
    compiling = summary["compile_s"]
    said = f"{compiling:.0f} s" if compiling >= 1 else f"{compiling:.1f} s"
    if compiling > 0 and not args.quiet:
        print(f"compiling the physics: {said}, kept in numba's cache for later runs")
    sharded = "" if "shards" not in summary else (
        f" in {summary['shards']} shard(s), {summary['kept']} kept from an earlier run "
        f"(index {summary['out']})")
    simulated = summary["simulated_s"]
    running = summary["wall_s"] - summary["compile_s"]  # the speed a later run will have
    rate = (f" ({simulated / running:.0f}x real time"
            + (f", the {said} of compiling aside" if compiling > 0 else "") + ")"
            if simulated > 0 and running > 0 else "")
    print(f"wrote {args.out}: {summary['missions']} mission(s){sharded}, "
          f"{simulated:g} s simulated in {summary['wall_s']:.1f} s{rate}")


def _presets(args: argparse.Namespace) -> None:
    from auvsim.runs.presets import DEFAULT_PRESET, PRESETS

    width = max(map(len, PRESETS)) + 2
    for name, (text, _) in PRESETS.items():
        mark = " (default)" if name == DEFAULT_PRESET else ""
        print(f"{name:{width}s} {text}{mark}")


def _inspect(args: argparse.Namespace) -> None:
    from auvsim.data.describe import describe

    print(without_negative_zero(describe(args.file)))


# A zero with a minus sign ("-0", "-0.", "-0.000", "-0.e+00"), not part of a word or of a
# longer number.
_NEGATIVE_ZERO = re.compile(r"(?<![\w.])-(0(?:\.0*)?(?:e[+-]0+)?)(?![\d.eE])")


def without_negative_zero(text: str) -> str:
    """``text`` with every negative zero (numpy's ``-0.``, a ``-0`` of ``:g``) written
    as zero: a sign on nothing reads as a value."""
    return _NEGATIVE_ZERO.sub(r"\1", text)


def _import_velocity(args: argparse.Namespace) -> None:
    from auvsim.data.importer import import_velocity
    from auvsim.data.writer import check_output_path
    from auvsim.runs.presets import preset

    check_output_path(args.out)

    dvl = dataclasses.replace(preset(args.preset).dvl, rate_hz=args.rate,
                              **({} if args.noise_std is None else
                                 {"noise_std": args.noise_std}))
    summary = import_velocity(args.files, args.out, dvl=dvl, seed=args.seed,
                              compression=args.compression)
    missions = ", ".join(f"{name} ({n} pings)" for name, n in summary.items())
    print(f"wrote {args.out}: {missions}; beams at {dvl.beam_angle_deg:g} deg, scale factor "
          f"{dvl.scale_factor}, bias {dvl.bias} m/s, noise {dvl.noise_std:g} m/s")


def _plot(args: argparse.Namespace) -> None:
    from auvsim.plot import plot

    for path in plot(args.file, missions=args.missions, out=args.out):
        print(f"wrote {path}")


def main(argv: list[str] | None = None) -> int:
    """Run a command line; returns the exit status: 0, 2 on an error, 130 on Ctrl-C or
    SIGTERM alike (after the workers have stopped and the temporary files have gone),
    141 when the reader of its output has gone (``auvsim.cli_support``)."""
    args = _parser().parse_args(argv)
    command = {"generate": _generate, "presets": _presets, "inspect": _inspect,
               "import-velocity": _import_velocity, "import": _import,
               "check-log": _check_log, "export": _export, "plot": _plot,
               "serve": _serve}[args.command]
    return run_command("auvsim", lambda: command(args), FLAGS)


def run() -> None:
    """The ``auvsim`` program (``exit_with``: its status, and a teardown Ctrl-C cannot
    break)."""
    exit_with("auvsim", main)


if __name__ == "__main__":
    run()
