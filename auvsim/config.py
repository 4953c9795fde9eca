"""The configuration: a few frozen dataclasses, validated on construction.

The resolved config is written into every dataset (``config_json``) and reads back to an
equal object (``Config.from_json(config.to_json()) == config``).
"""

from __future__ import annotations

import dataclasses
import json
import math
import operator
import os
import reprlib
from dataclasses import dataclass, field

from auvsim.checks import did_you_mean, is_finite
from auvsim.errors import ConfigError
from auvsim.physics.maneuvers import MANEUVERS, check_scenario
from auvsim.sensors import registry

SCENARIOS = tuple(MANEUVERS)  # the manoeuvres' registry is the one list of names
SEAFLOORS = ("flat", "procedural", "heightmap", "grid")
GRID_NODATA = ("refuse", "fill")  # SeafloorConfig.nodata
GRID_POSITIVE = ("up", "down")  # SeafloorConfig.grid_positive

# Bounds that keep a config's run finite and its physics meaningful (a config beyond them
# is refused, naming the field).
# A mission lasts at most 72 h: three times the endurance of the longest-lived vehicle
# auvsim models, the A18-D's 24 h (../shared/reference/vehicles.md), which leaves room for
# the 200,000 s (56 h) missions the tests use as "long".
MAX_DURATION = 72 * 3600.0  # s
# A dataset holds at most 1000 missions (the presets have up to 10) and 30 days of
# simulated time in all: about 45 GB of HDF5 at 17 kB per simulated second, and about two
# hours of two cores at 450x real time. A bigger dataset is better made as several files.
MAX_MISSIONS = 1000
MAX_TOTAL_DURATION = 30 * 24 * 3600.0  # s
# Surge speeds. The models reach 3.66 m/s (A18-D) and 2.55 m/s (REMUS 100; models/README.md).
# A set point is held to 95 % of the vehicle's own top speed (Vehicle.check_speed); this bound
# only keeps a manoeuvre's plan finite. A start beyond the top speed is a launch: at 5 m/s
# the REMUS 100 rolls by up to 45 deg before it slows down, at 10 m/s by up to 80 deg.
MAX_SPEED = 10.0  # m/s, set
MAX_START_SPEED = 5.0  # m/s, initial
# The current, in magnitude: the strongest ocean currents, such as the Gulf Stream, peak at
# about 2.5 m/s, and against a current beyond the vehicle's top speed (about 3 m/s) no
# mission can be flown.
MAX_CURRENT = 3.0  # m/s
# Buoyancy minus weight, in magnitude: 1 kN is 14 % of the A18-D's 7.2 kN weight and three
# times the REMUS 100's whole weight (AUVs are trimmed close to neutral). The A18-D holds
# depth with it and the REMUS 100 leaves its depth within seconds (an error naming the
# time); from about 1e6 N on the REMUS 100 (1e8 N on the A18-D) MuJoCo's integration
# blows up, and it resets the vehicle to rest.
MAX_NET_BUOYANCY = 1000.0  # N
# A sensor's offset from the body origin, per axis: the vehicles auvsim models are at most
# 5.5 m long (the A18-D), so 10 m holds any sensor on them and on a vehicle twice as long.
MAX_SENSOR_OFFSET = 10.0  # m
SPEED_CONTROLS = ("speed", "rpm")  # VehicleConfig.speed_control
HEADING_CONTROLS = ("pid", "full-rudder-turns")  # VehicleConfig.heading_control
# Depths of the water, the seafloor and the terrain: the deepest ocean, the Challenger
# Deep, is about 10.9 km deep.
MAX_DEPTH = 11000.0  # m
# Grid spacings up to 1 km: global bathymetry grids such as GEBCO's (15 arc-seconds) are
# about 460 m. Procedural terrain is held in a window of 1024 cells a side around the
# vehicle (auvsim.world.seafloor): cells of at least 0.5 m keep it at least 512 m wide, more than
# a 60 s block's track at the A18-D's top speed in the strongest current and its length
# (about 400 m); finer cells made a window the track outran.
MAX_CELL_SIZE = 1000.0  # m
MIN_PROCEDURAL_CELL_SIZE = 0.5  # m
# A bathymetry grid's mission area is a square of at most 100 km a side around the
# location: the flat world's north and east are read as arc lengths at the origin's radii
# of curvature (auvsim.world.grid), which stray from the exact local NED frame by about
# (d / R)^2 d: 2 mm at 5 km, 0.3 m at 50 km from the origin.
MAX_GRID_EXTENT = 100_000.0  # m
# Terrain features up to 1000 cells long: the procedural terrain is a field on a grid of
# at most 2048 cells a side (auvsim.world.seafloor), and from about 24,000 cells on the filter
# leaves it constant, whose unit std is 0 / 0 (NaN heights).
MAX_CORRELATION_CELLS = 1000
# Angles (headings, slope heading, DVL mounting) within a turn either way.
MAX_ANGLE = 360.0  # deg
# DVLs ping at 1 Hz or faster (1 Hz in the paper's data, 5 Hz for the Water Linked A50:
# ../shared/reference/sensors.md). At least 0.1 Hz keeps generate's blocks (a whole number
# of pings) near 60 s, which the procedural terrain window is sized for: at 0.001 Hz a
# block of 1000 s outran the window.
MIN_DVL_RATE = 0.1  # Hz
# The DVL's realised sound-speed error: by Medwin's formula (the one Teledyne RDI's ADCP
# manuals use) sea water's sound speed spans about 1440 to 1550 m/s near the surface over
# 0-30 deg C and 30-38 psu, and reaches about 1570 m/s deep: within about 5 % of the
# 1500 m/s a DVL assumes, so a spread of 5 % already covers the whole ocean.
MAX_SOUND_SPEED_STD = 0.05
# A realised DVL mounting misalignment is a residual after installation, a fraction of a
# degree to a degree; beyond 10 deg (per axis, 1 sigma) it is a mounting, not a
# misalignment (our choice).
MAX_MISALIGNMENT_STD = 10.0  # deg


def _shown(value: object) -> str:
    """A value as an error message shows it: its repr, shortened if long or deep."""
    return _REPR.repr(value)


_REPR = reprlib.Repr()
_REPR.maxstring = _REPR.maxother = 120
_REPR.maxlevel = 3


def _check(ok: bool, name: str, expected: str, got: object) -> None:
    if not ok:
        raise ConfigError(f"{name}: expected {expected}, got {_shown(got)}")


def _finite(name: str, value: float) -> None:
    _check(is_finite(value), name, "a finite number", value)


def _angle(name: str, value: float) -> None:
    _finite(name, value)
    _check(abs(value) <= MAX_ANGLE, name, f"an angle in [-{MAX_ANGLE:g}, {MAX_ANGLE:g}] deg",
           value)


@dataclass(frozen=True)
class VehicleConfig:
    """Which vehicle, and the water around it.

    Attributes:
        model: ``auv`` (A18-D class), ``remus100`` or a path to an MJCF model.
        net_buoyancy: buoyancy minus weight, N (positive floats up); at most
            ``MAX_NET_BUOYANCY`` (1 kN) in magnitude.
        current_ned: constant ocean current, m/s, NED; at most ``MAX_CURRENT`` (3 m/s) in
            magnitude (with the ``water`` section's current added). The speed autopilot
            holds the speed through the water, so since schema v4 a closed-loop mission in
            a current flies at its set speed relative to the water, not over ground.
        speed_control: ``speed`` (the default: the speed loop holds the set speed through
            the water, raising the rpm in a turn) or ``rpm`` (the shaft holds the rpm that
            gives the set speed in straight flight, as a real AUV commands propeller rpm, so
            the vehicle slows in a turn; ``auvsim.physics.control.Gains.hold_rpm``).
        heading_control: ``pid`` (the default: the heading PID throughout, whose yaw-rate
            term backs the rudder off as a turn builds) or ``full-rudder-turns`` (a heading
            change beyond the PID's braking point flown at full rudder, as a survey AUV
            turns at the end of its lines; ``Gains.full_rudder_turns``).
        imu_position, dvl_position: where the IMU and the DVL sit, m, body FRD from the
            body origin (the centre of buoyancy), each axis within ``MAX_SENSOR_OFFSET``
            (10 m) either way, on the hull or off it (a towed or pole-mounted sensor);
            ``None`` (the default) takes the model's ``imu`` and ``dvl`` sites. Each
            measures at its own position: in a turn the DVL sees ``omega x r`` more velocity
            than the origin, the IMU ``d omega/dt x r + omega x (omega x r)`` more specific
            force.
    """

    model: str = "auv"
    net_buoyancy: float = 0.0
    current_ned: tuple[float, float, float] = (0.0, 0.0, 0.0)
    speed_control: str = "speed"
    heading_control: str = "pid"
    imu_position: tuple[float, float, float] | None = None
    dvl_position: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        _check(isinstance(self.model, str) and self.model != "", "vehicle.model",
               "a vehicle name or model path", self.model)
        _finite("vehicle.net_buoyancy", self.net_buoyancy)
        _check(self.speed_control in SPEED_CONTROLS, "vehicle.speed_control",
               f"one of {', '.join(SPEED_CONTROLS)}", self.speed_control)
        _check(self.heading_control in HEADING_CONTROLS, "vehicle.heading_control",
               f"one of {', '.join(HEADING_CONTROLS)}", self.heading_control)
        _check(abs(self.net_buoyancy) <= MAX_NET_BUOYANCY, "vehicle.net_buoyancy",
               f"at most {MAX_NET_BUOYANCY:g} N either way (a trimmed vehicle's buoyancy "
               "minus weight)", self.net_buoyancy)
        object.__setattr__(self, "current_ned",
                           _vector("vehicle.current_ned", self.current_ned, 3))
        for name in ("imu_position", "dvl_position"):
            value = getattr(self, name)
            if value is not None:
                value = _vector(f"vehicle.{name}", value, 3)
                _check(all(abs(v) <= MAX_SENSOR_OFFSET for v in value), f"vehicle.{name}",
                       f"an offset of at most {MAX_SENSOR_OFFSET:g} m on each axis (a "
                       "sensor on the vehicle)", value)
                object.__setattr__(self, name, value)
        speed = math.hypot(*self.current_ned)
        if speed > MAX_CURRENT:
            raise ConfigError(f"vehicle.current_ned: expected a current of at most "
                              f"{MAX_CURRENT:g} m/s (the strongest ocean currents are about "
                              f"2.5 m/s), got {self.current_ned} ({speed:.4g} m/s)")


@dataclass(frozen=True)
class ScenarioConfig:
    """What the vehicle is asked to do.

    Attributes:
        name: one of ``SCENARIOS``.
        speed: surge speed to hold, m/s.
        heading_deg: heading to hold, degrees from north, in [-360, 360].
        depth: depth to hold, m, at most ``MAX_DEPTH`` (11 km, the deepest ocean).
        duration: mission length, s, at most ``MAX_DURATION``: 72 h, three times the
            A18-D's 24 h endurance (the model card's vehicle figures), which keeps every
            accepted run finite (a dataset also holds at most ``MAX_MISSIONS``, 1000, and
            ``MAX_TOTAL_DURATION``, 30 days, in all).
        start_speed: initial surge speed, m/s; ``None`` starts at ``speed`` (on the set
            point, so the data is steady from the first sample); at most
            ``MAX_START_SPEED`` (5 m/s, above the models' top speeds of 3.66 and 2.55 m/s).
            Set points (``speed``) are held to 95 % of the vehicle's own top speed
            (``Vehicle.check_speed``).
        options: the manoeuvre's own parameters by name (``auvsim.physics.maneuvers``; each class
            lists its options and their defaults).
    """

    name: str = "straight"
    speed: float = 2.0
    heading_deg: float = 0.0
    depth: float = 20.0
    duration: float = 600.0
    start_speed: float | None = None
    options: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.name not in SCENARIOS:
            raise ConfigError(f"scenario: expected one of {', '.join(SCENARIOS)}, got "
                              f"{_shown(self.name)}{did_you_mean(self.name, SCENARIOS)}")
        for name in ("speed", "heading_deg", "depth", "duration"):
            _finite(f"scenario.{name}", getattr(self, name))
        _check(self.duration > 0, "duration", "a positive number of seconds", self.duration)
        _check(self.duration <= MAX_DURATION, "duration",
               f"at most {MAX_DURATION:g} s (72 h, three times the A18-D's 24 h endurance)",
               self.duration)
        _check(self.speed > 0, "speed", "a positive speed in m/s", self.speed)
        _check(self.speed <= MAX_SPEED, "speed", f"at most {MAX_SPEED:g} m/s, any vehicle's "
               "bound (the vehicle's own top speed, lower, is checked next)", self.speed)
        _check(self.depth > 0, "depth", "a positive depth in m", self.depth)
        _check(self.depth <= MAX_DEPTH, "depth",
               f"at most {MAX_DEPTH:g} m (the deepest ocean)", self.depth)
        _angle("scenario.heading_deg", self.heading_deg)
        if self.start_speed is not None:
            _finite("scenario.start_speed", self.start_speed)
            _check(self.start_speed >= 0, "start_speed", "a speed >= 0 m/s", self.start_speed)
            _check(self.start_speed <= MAX_START_SPEED, "start_speed",
                   f"at most {MAX_START_SPEED:g} m/s", self.start_speed)
        _check(isinstance(self.options, dict), "scenario.options",
               "a table of option names and numbers", self.options)
        check_scenario(self)  # the options, against the manoeuvre's


@dataclass(frozen=True)
class MissionConfig:
    """One mission of a dataset: a scenario and the seed of its random streams."""

    name: str = "mission_000"
    scenario: ScenarioConfig = field(default_factory=ScenarioConfig)
    seed: int = 0

    def __post_init__(self) -> None:
        _check(isinstance(self.name, str) and self.name.isidentifier(), "mission.name",
               "a name of letters, digits and underscores", self.name)
        if not isinstance(self.seed, (int, float)) and hasattr(type(self.seed), "__index__"):
            object.__setattr__(self, "seed", operator.index(self.seed))  # a numpy integer
        _check(isinstance(self.seed, int) and not isinstance(self.seed, bool)
               and 0 <= self.seed < 2**63, "seed", "an integer in [0, 2**63)", self.seed)
        _check(isinstance(self.scenario, ScenarioConfig), "mission.scenario",
               "a ScenarioConfig", type(self.scenario).__name__)


@dataclass(frozen=True)
class SeafloorConfig:
    """The seafloor the DVL beams hit.

    Attributes:
        kind: ``flat`` (a plane), ``procedural`` (seeded random terrain on a plane that may
            slope), ``heightmap`` (a user's grid of depths) or ``grid`` (a georeferenced
            bathymetry grid, GeoTIFF or NetCDF).
        depth: depth of the plane at the mission start (0, 0), m.
        roughness: standard deviation of the terrain about the plane, m (procedural).
        correlation_length: horizontal scale of the terrain's features, m (procedural).
        slope_deg: slope of the plane, degrees (procedural).
        slope_heading_deg: direction in which the plane gets deeper, degrees from north.
        heightmap: path of a ``.npy`` (rows, cols) array of depths in m, positive down; rows
            run north, columns east, centred on the mission start (heightmap). At most
            4096 x 4096 depths, each within 11 km of the surface (``auvsim.world.seafloor``).
        cell_size: grid spacing, m: of the heightmap, and of the terrain grid MuJoCo
            ray-casts against (procedural); at most ``MAX_CELL_SIZE`` (1 km), and for
            procedural terrain at least ``MIN_PROCEDURAL_CELL_SIZE`` (0.5 m) and
            ``correlation_length / MAX_CORRELATION_CELLS``. Unused by a grid, whose
            heightmap takes the grid's own spacing.
        grid: path of a georeferenced bathymetry grid (grid): a GeoTIFF (``.tif``,
            ``.tiff``, read with rasterio) or a NetCDF file (``.nc``, read with xarray), on
            geographic WGS-84 latitude and longitude, north up. The missions are placed on
            it by ``Config.location``; it is cropped to ``extent`` and resampled
            (bilinearly) onto a heightmap at its own spacing (``auvsim.world.grid``).
        grid_variable: the NetCDF variable holding the grid (None: the only 2-D variable
            on latitude and longitude); unused for a GeoTIFF (band 1).
        grid_positive: ``up`` (the grid holds elevations, negative below sea level, as
            GEBCO and ETOPO do) or ``down`` (it holds depths, positive below sea level).
        nodata: what a nodata cell of the grid within the mission area does: ``refuse``
            (a config error naming how many) or ``fill`` (each takes the mean of its valid
            4-neighbours, ring by ring inward from the hole's edge: nearest-neighbour
            filling).
        extent: side of the square mission area centred on the location, m, at most
            ``MAX_GRID_EXTENT`` (100 km): the part of the grid the heightmap covers.
        grid_sha256: SHA-256 of the grid file, hex; ``auvsim generate`` fills it in (and
            refuses a file that no longer matches it), so the config stored in a dataset
            names the grid by path and content.

    Depths (``depth``, and ``roughness``) are at most ``MAX_DEPTH`` (11 km, the deepest
    ocean); ``slope_heading_deg`` is in [-360, 360].
    """

    kind: str = "flat"
    # 60 m, the presets' coastal floor: the default DVL (30 deg beams, 90 m range) reaches
    # it from the default 20 m (46 m away), where a 100 m floor left every beam 92 m away,
    # beyond its range, and a bare Config() without bottom lock.
    depth: float = 60.0
    roughness: float = 0.0
    correlation_length: float = 30.0
    slope_deg: float = 0.0
    slope_heading_deg: float = 0.0
    heightmap: str | None = None
    cell_size: float = 2.0
    grid: str | None = None
    grid_variable: str | None = None
    grid_positive: str = "up"
    nodata: str = "refuse"
    extent: float = 4000.0
    grid_sha256: str | None = None

    def __post_init__(self) -> None:
        _check(self.kind in SEAFLOORS, "seafloor.kind", f"one of {', '.join(SEAFLOORS)}",
               self.kind)
        for name in ("depth", "roughness", "correlation_length", "slope_deg",
                     "slope_heading_deg", "cell_size"):
            _finite(f"seafloor.{name}", getattr(self, name))
        _check(self.depth > 0, "seafloor.depth", "a positive depth in m", self.depth)
        _check(self.depth <= MAX_DEPTH, "seafloor.depth",
               f"at most {MAX_DEPTH:g} m (the deepest ocean)", self.depth)
        _check(self.roughness >= 0, "seafloor.roughness", "a height std >= 0 m", self.roughness)
        _check(self.roughness <= MAX_DEPTH, "seafloor.roughness",
               f"a height std of at most {MAX_DEPTH:g} m (the deepest ocean)", self.roughness)
        _check(self.correlation_length > 0, "seafloor.correlation_length", "a length > 0 m",
               self.correlation_length)
        _check(0 <= self.slope_deg < 45, "seafloor.slope_deg", "a slope in [0, 45) deg",
               self.slope_deg)
        _angle("seafloor.slope_heading_deg", self.slope_heading_deg)
        _check(self.cell_size > 0, "seafloor.cell_size", "a spacing > 0 m", self.cell_size)
        _check(self.cell_size <= MAX_CELL_SIZE, "seafloor.cell_size",
               f"a spacing of at most {MAX_CELL_SIZE:g} m", self.cell_size)
        _check(self.kind != "procedural" or self.cell_size >= MIN_PROCEDURAL_CELL_SIZE,
               "seafloor.cell_size", f"a spacing of at least {MIN_PROCEDURAL_CELL_SIZE:g} m "
               "for procedural terrain (its window is 1024 cells wide)", self.cell_size)
        _check(self.kind != "procedural"
               or self.correlation_length <= MAX_CORRELATION_CELLS * self.cell_size,
               "seafloor.correlation_length",
               f"a length of at most {MAX_CORRELATION_CELLS} cells "
               f"({MAX_CORRELATION_CELLS * self.cell_size:g} m at {self.cell_size:g} m cells)",
               self.correlation_length)
        _check((self.kind == "heightmap") == (self.heightmap is not None), "seafloor.heightmap",
               "a .npy path exactly when kind is heightmap", self.heightmap)
        _check(self.heightmap is None or isinstance(self.heightmap, str), "seafloor.heightmap",
               "a path to a .npy file", self.heightmap)
        _check((self.kind == "grid") == (self.grid is not None), "seafloor.grid",
               "a GeoTIFF or NetCDF path exactly when kind is grid", self.grid)
        _check(self.grid is None or (isinstance(self.grid, str) and self.grid != ""),
               "seafloor.grid", "a path to a GeoTIFF or NetCDF file", self.grid)
        _check(self.grid_variable is None or (isinstance(self.grid_variable, str)
                                              and self.grid_variable != ""),
               "seafloor.grid_variable", "a NetCDF variable name", self.grid_variable)
        _check(self.grid_positive in GRID_POSITIVE, "seafloor.grid_positive",
               "up (elevations, as GEBCO's) or down (depths)", self.grid_positive)
        _check(self.nodata in GRID_NODATA, "seafloor.nodata", "refuse or fill", self.nodata)
        _finite("seafloor.extent", self.extent)
        _check(0 < self.extent <= MAX_GRID_EXTENT, "seafloor.extent",
               f"a side in (0, {MAX_GRID_EXTENT:g}] m", self.extent)
        _check(self.grid_sha256 is None or (
            isinstance(self.grid_sha256, str) and len(self.grid_sha256) == 64
            and all(c in "0123456789abcdef" for c in self.grid_sha256)),
            "seafloor.grid_sha256", "64 lowercase hex digits", self.grid_sha256)


@dataclass(frozen=True)
class DvlConfig:
    """A four-beam Janus DVL and its error model (paper eq. 7, per beam k):
    ``y_k = (1 + s_k) (b_k . v) + bias_k + n_k``, ``n_k ~ N(0, noise_std^2)``.

    The realised s and bias of a mission are ``scale_factor + scale_factor_std * N(0, 1)``
    and ``bias + bias_std * N(0, 1)`` per beam, drawn from the mission's seed and stored in
    its attributes. A scalar means all four beams alike.

    Attributes:
        rate_hz: ping rate, at least ``MIN_DVL_RATE`` (0.1 Hz); the IMU rate must be a whole
            multiple of it.
        beam_angle_deg: angle of each beam from the DVL's z (down) axis.
        mounting_rpy_deg: roll, pitch, yaw of the DVL frame relative to the body (ZYX),
            each in [-360, 360].
        min_range, max_range: slant ranges, m, between which a beam has bottom lock.
        scale_factor, scale_factor_std: s (dimensionless): mean, and per-mission spread.
        bias, bias_std: m/s.
        noise_std: m/s, white noise per beam and ping.

        Bottom lock lost as an instrument loses it, per beam and ping (each off by
        default; ``auvsim.sensors.dvl`` gives the reason codes of ``dvl/status``):

        echo_loss_range: m, slant range at which an echo is lost with probability 1/2
            (``None``: off); the probability is the logistic
            ``1 / (1 + exp(-(r - echo_loss_range) / echo_loss_width))``.
        echo_loss_width: m, > 0, the width of that curve.
        grazing_loss_angle_deg: incidence angle (beam against the seafloor normal at its
            hit), deg in (0, 90), lost with probability 1/2 (``None``: off); the same
            logistic in the angle, of width ``grazing_loss_width_deg`` (> 0).
        dropout_rate: stationary share of beam-pings inside a dropout burst, in [0, 1);
            each beam is a two-state Markov chain (lock, dropout) per ping.
        dropout_burst: mean burst length in pings, >= 1 (a burst ends with probability
            1 / dropout_burst per ping); the rate is at most
            ``dropout_burst / (1 + dropout_burst)``, else a burst could not start often
            enough.
        ping_dropout_rate: share of whole pings lost (every beam), in [0, 1).
        beam_failures: ``((beam, start_s, end_s), ...)``, beam 0..3 dead for
            ``start_s <= t < end_s``.
        lock_loss_intervals: ``((start_s, end_s), ...)``: every beam loses bottom lock (a
            soft bottom) for ``start_s <= t < end_s``.

        Measurement errors beyond eq. 7 (each off by default):

        noise_range_coeff: m/s per m of slant range, >= 0: the beam noise std grows as
            ``noise_std + noise_range_coeff * r + noise_speed_coeff * |v|``.
        noise_speed_coeff: dimensionless (m/s of std per m/s of speed), >= 0.
        outlier_rate: share of beam-pings that are outliers, in [0, 1).
        outlier_std: m/s, >= 0, the scale of their heavy-tailed (Student t, 3 degrees of
            freedom) error.
        sound_speed_std: spread of the realised ratio ``c_true / c_assumed - 1``, in
            [0, 0.05] (``MAX_SOUND_SPEED_STD``); the measured beams are divided by the
            ratio.
        misalignment_std_deg: deg, in [0, 10]: spread of the realised mounting misalignment
            per axis (the geometry uses it, the user's ``mounting_rpy_deg`` stays nominal).
        water_track: fall back to water track on a ping with fewer than 3 beams in
            bottom lock (no bottom-track velocity).
        water_track_range: m, > 0 (at most ``max_range`` with water track on): distance
            below the DVL of the water layer it tracks.
        water_track_noise_std: m/s, >= 0: the beam noise in water track (in place of the
            bottom-track noise).
        slow_error_std: m/s, >= 0: std of a time-correlated velocity error, per DVL axis,
            that the measured beams share (``H dv``): first-order Gauss-Markov, started
            stationary. It survives averaging and lies in the span of the beams, so the
            error velocity does not see it (the white beam noise is what that shows).
        slow_error_time: s, > 0: its correlation time.
    """

    rate_hz: float = 1.0
    beam_angle_deg: float = 30.0
    mounting_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    min_range: float = 0.7
    max_range: float = 90.0
    scale_factor: float | tuple[float, float, float, float] = 0.0
    scale_factor_std: float = 0.0
    bias: float | tuple[float, float, float, float] = 0.0
    bias_std: float = 0.0
    noise_std: float = 0.0
    echo_loss_range: float | None = None
    echo_loss_width: float = 5.0
    grazing_loss_angle_deg: float | None = None
    grazing_loss_width_deg: float = 5.0
    dropout_rate: float = 0.0
    dropout_burst: float = 1.0
    ping_dropout_rate: float = 0.0
    beam_failures: tuple[tuple[int, float, float], ...] = ()
    lock_loss_intervals: tuple[tuple[float, float], ...] = ()
    noise_range_coeff: float = 0.0
    noise_speed_coeff: float = 0.0
    outlier_rate: float = 0.0
    outlier_std: float = 0.0
    sound_speed_std: float = 0.0
    misalignment_std_deg: float = 0.0
    water_track: bool = False
    water_track_range: float = 10.0
    water_track_noise_std: float = 0.0
    slow_error_std: float = 0.0
    slow_error_time: float = 600.0

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):  # every plain number; the rest below
            if f.type in ("float", float):
                _finite(f"dvl.{f.name}", getattr(self, f.name))
        _check(self.rate_hz > 0, "dvl.rate_hz", "a positive rate in Hz", self.rate_hz)
        _check(self.rate_hz >= MIN_DVL_RATE, "dvl.rate_hz",
               f"a rate of at least {MIN_DVL_RATE:g} Hz", self.rate_hz)
        _check(0 < self.beam_angle_deg < 90, "dvl.beam_angle_deg", "an angle in (0, 90) deg",
               self.beam_angle_deg)
        _check(0 <= self.min_range < self.max_range, "dvl.min_range, dvl.max_range",
               "0 <= min_range < max_range (m)", (self.min_range, self.max_range))
        for name in ("scale_factor_std", "bias_std", "noise_std"):
            _check(getattr(self, name) >= 0, f"dvl.{name}", "a standard deviation >= 0",
                   getattr(self, name))
        object.__setattr__(self, "mounting_rpy_deg", _vector("dvl.mounting_rpy_deg",
                                                             self.mounting_rpy_deg, 3))
        _check(all(abs(a) <= MAX_ANGLE for a in self.mounting_rpy_deg), "dvl.mounting_rpy_deg",
               f"angles in [-{MAX_ANGLE:g}, {MAX_ANGLE:g}] deg", self.mounting_rpy_deg)
        for name in ("scale_factor", "bias"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)):
                object.__setattr__(self, name, _vector(f"dvl.{name}", value, 4))
            else:
                _finite(f"dvl.{name}", value)
        self._check_lock_loss()
        for name in ("noise_range_coeff", "noise_speed_coeff", "outlier_std",
                     "water_track_noise_std", "slow_error_std"):
            _check(getattr(self, name) >= 0, f"dvl.{name}", "a value >= 0",
                   getattr(self, name))
        _check(0 <= self.outlier_rate < 1, "dvl.outlier_rate", "a share in [0, 1)",
               self.outlier_rate)
        _check(0 <= self.sound_speed_std <= MAX_SOUND_SPEED_STD, "dvl.sound_speed_std",
               f"a spread in [0, {MAX_SOUND_SPEED_STD:g}]", self.sound_speed_std)
        _check(0 <= self.misalignment_std_deg <= MAX_MISALIGNMENT_STD, "dvl.misalignment_std_deg",
               f"a spread in [0, {MAX_MISALIGNMENT_STD:g}] deg", self.misalignment_std_deg)
        _check(isinstance(self.water_track, bool), "dvl.water_track", "true or false",
               self.water_track)
        _check(self.water_track_range > 0, "dvl.water_track_range", "a distance > 0 m",
               self.water_track_range)
        _check(self.slow_error_time > 0, "dvl.slow_error_time", "a correlation time > 0 s",
               self.slow_error_time)
        _check(not self.water_track or self.water_track_range <= self.max_range,
               "dvl.water_track_range", f"a distance of at most max_range = "
               f"{self.max_range:g} m with water_track on", self.water_track_range)

    def _check_lock_loss(self) -> None:
        """The settings of lost bottom lock (normalised to tuples, so that the JSON round
        trip gives an equal config)."""
        for name, limit in (("echo_loss_range", None), ("grazing_loss_angle_deg", 90.0)):
            value = getattr(self, name)
            if value is not None:
                _finite(f"dvl.{name}", value)
                _check(value > 0 and (limit is None or value < limit), f"dvl.{name}",
                       "a range > 0 m (or null: off)" if limit is None
                       else "an angle in (0, 90) deg (or null: off)", value)
        for name in ("echo_loss_width", "grazing_loss_width_deg"):
            _check(getattr(self, name) > 0, f"dvl.{name}", "a width > 0", getattr(self, name))
        _check(0 <= self.dropout_rate < 1, "dvl.dropout_rate", "a share in [0, 1)",
               self.dropout_rate)
        _check(self.dropout_burst >= 1, "dvl.dropout_burst", "a mean burst length >= 1 ping",
               self.dropout_burst)
        most = self.dropout_burst / (1 + self.dropout_burst)
        _check(self.dropout_rate <= most, "dvl.dropout_rate",
               f"a share of at most dropout_burst / (1 + dropout_burst) = {most:g} (bursts "
               f"of {self.dropout_burst:g} pings cannot start more often)", self.dropout_rate)
        _check(0 <= self.ping_dropout_rate < 1, "dvl.ping_dropout_rate", "a share in [0, 1)",
               self.ping_dropout_rate)
        object.__setattr__(self, "beam_failures", _intervals(
            "dvl.beam_failures", self.beam_failures, beam=True))
        object.__setattr__(self, "lock_loss_intervals", _intervals(
            "dvl.lock_loss_intervals", self.lock_loss_intervals, beam=False))


def _intervals(name: str, value, *, beam: bool) -> tuple:
    """Time intervals ``((start_s, end_s), ...)``, or ``((beam, start_s, end_s), ...)``
    with a beam index 0..3, as tuples; 0 <= start < end, finite."""
    expected = ("a list of (beam 0..3, start_s, end_s) with 0 <= start_s < end_s" if beam
                else "a list of (start_s, end_s) with 0 <= start_s < end_s")
    out = []
    try:
        items = list(value) if not isinstance(value, (str, bytes)) else None
    except TypeError:
        items = None
    _check(items is not None, name, expected, value)
    for item in items:
        ok = (not isinstance(item, (str, bytes)) and hasattr(item, "__len__")
              and len(item) == (3 if beam else 2))
        if ok and beam:
            ok = (not isinstance(item[0], bool) and isinstance(item[0], int)
                  and 0 <= item[0] <= 3)
        times = tuple(item[1:] if beam else item) if ok else ()
        ok = ok and all(is_finite(t) for t in times) and 0 <= times[0] < times[1]
        _check(ok, name, expected, value)
        out.append((int(item[0]), float(times[0]), float(times[1])) if beam
                   else (float(times[0]), float(times[1])))
    return tuple(out)


# IMU scale-factor, misalignment and g-sensitivity errors are first-order (small) terms of
# the sensor model (Groves, Principles of GNSS, Inertial, and Multisensor Integrated
# Navigation Systems, 2nd ed., 2013, eqs. 4.16-4.17). The worst IMU of Groves' examples,
# his consumer grade (Inertial_Demo_3.m of the book's software), has scale factors up to
# 6 %, cross-coupling up to 1.5 % (0.015 rad) and g-dependent gyro biases up to
# 190 deg/h/g (9.4e-5 rad/s per m/s^2). Our bounds leave room above it and keep the terms
# small: a 10 % scale factor; 0.05 rad (2.9 deg) of misalignment, where (I + M) departs
# from a rotation's matrix by about 0.05^2 / 2 = 0.1 %; and 1e-3 rad/s per m/s^2 (0.56
# deg/s of rate from gravity alone), ten times Groves' consumer grade.
MAX_IMU_SCALE_FACTOR_STD = 0.1
MAX_IMU_MISALIGNMENT_STD = 0.05  # rad
MAX_GYRO_G_SENSITIVITY_STD = 1e-3  # rad/s per m/s^2
# A vibration's std per axis (and its growth per rad/s of yaw rate): 1 g and 1 rad/s (57
# deg/s) are far above the tens to hundreds of mm/s^2 and deg/h a survey AUV's IMU records
# above 10 Hz (``benchmarks/imu_spectrum.py``) and still small beside a navigation IMU's
# ranges.
MAX_IMU_VIBRATION_ACCEL = 9.80665  # m/s^2
MAX_IMU_VIBRATION_GYRO = 1.0  # rad/s


@dataclass(frozen=True)
class ImuConfig:
    """IMU error model (``auvsim.sensors.imu`` states it in full), per triad:
    ``measured = (I + S + M) true + turn_on_bias + b(t) + white noise``, and for the gyros
    ``+ G f`` (g-sensitivity, f the true specific force). S (diagonal scale factors), M
    (off-diagonal misalignment) and G are drawn per mission, N(0, std^2) per element; b(t)
    is a first-order Gauss-Markov process with steady-state std ``*_bias_instability``;
    white noise std = density * sqrt(rate). The true values are those of a flat world that
    does not rotate, or with a geographic origin (``Config.location``) of the rotating
    Earth there: the gyros' true rate includes the Earth's, the true specific force the
    WGS-84 normal gravity and the Coriolis term (``LocationConfig``).

    Attributes:
        rate_hz: sample rate; also the rate of the truth group.
        accel_noise_density: m/s^2/sqrt(Hz) (velocity random walk).
        gyro_noise_density: rad/s/sqrt(Hz) (angle random walk).
        accel_turn_on_bias, gyro_turn_on_bias: std of the constant bias drawn per mission
            (m/s^2, rad/s).
        accel_bias_instability, gyro_bias_instability: std of the Gauss-Markov bias
            (m/s^2, rad/s).
        bias_correlation_time: s, the Gauss-Markov correlation time of both triads unless
            one of the two below is set (the one setting of configs before them).
        accel_bias_correlation_time, gyro_bias_correlation_time: s, each triad's own
            correlation time; ``None`` takes ``bias_correlation_time``.
        accel_scale_factor_std, gyro_scale_factor_std: std of each axis's scale-factor
            error (dimensionless, 1e-6 = 1 ppm), at most ``MAX_IMU_SCALE_FACTOR_STD``.
        accel_misalignment_std, gyro_misalignment_std: std of each of the six off-diagonal
            cross-coupling terms (rad: non-orthogonality and mounting), at most
            ``MAX_IMU_MISALIGNMENT_STD``.
        gyro_g_sensitivity_std: std of each of the nine elements of G (rad/s per m/s^2),
            at most ``MAX_GYRO_G_SENSITIVITY_STD``.
        accel_vibration_std, gyro_vibration_std: (3,) the std per axis (m/s^2, rad/s) of
            the vibration the triad records on its vehicle without rotation, added to every
            sample: zero mean and no power at zero frequency (``auvsim.sensors.imu`` gives
            its spectrum), so it integrates to a bounded velocity and angle. Zero: none.
        accel_vibration_per_rate, gyro_vibration_per_rate: (3,) the growth of that std
            per rad/s of the magnitude of the true body-z rate the gyros sense (m/s^2 and
            rad/s per rad/s): the std at a sample is ``*_vibration_std +
            *_vibration_per_rate |r|``.
    """

    rate_hz: float = 100.0
    accel_noise_density: float = 0.0
    gyro_noise_density: float = 0.0
    accel_turn_on_bias: float = 0.0
    gyro_turn_on_bias: float = 0.0
    accel_bias_instability: float = 0.0
    gyro_bias_instability: float = 0.0
    bias_correlation_time: float = 3600.0
    accel_bias_correlation_time: float | None = None
    gyro_bias_correlation_time: float | None = None
    accel_scale_factor_std: float = 0.0
    gyro_scale_factor_std: float = 0.0
    accel_misalignment_std: float = 0.0
    gyro_misalignment_std: float = 0.0
    gyro_g_sensitivity_std: float = 0.0
    accel_vibration_std: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gyro_vibration_std: tuple[float, float, float] = (0.0, 0.0, 0.0)
    accel_vibration_per_rate: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gyro_vibration_per_rate: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for name, bound, unit in (
                ("accel_vibration_std", MAX_IMU_VIBRATION_ACCEL, "m/s^2"),
                ("gyro_vibration_std", MAX_IMU_VIBRATION_GYRO, "rad/s"),
                ("accel_vibration_per_rate", MAX_IMU_VIBRATION_ACCEL, "m/s^2 per rad/s"),
                ("gyro_vibration_per_rate", MAX_IMU_VIBRATION_GYRO, "rad/s per rad/s")):
            value = _vector(f"imu.{name}", getattr(self, name), 3)
            _check(all(0 <= v <= bound for v in value), f"imu.{name}",
                   f"3 values in [0, {bound:g}] {unit}", getattr(self, name))
            object.__setattr__(self, name, value)
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if (value is None and f.name in _IMU_OPTIONAL) or f.name in _IMU_VIBRATION:
                continue
            _finite(f"imu.{f.name}", value)
            _check(value >= 0, f"imu.{f.name}", "a value >= 0", value)
        _check(self.rate_hz > 0, "imu.rate_hz", "a positive rate in Hz", self.rate_hz)
        for name in ("bias_correlation_time", *_IMU_OPTIONAL):
            value = getattr(self, name)
            _check(value is None or value > 0, f"imu.{name}", "a time > 0 s", value)
        for name, bound, unit in (
                ("accel_scale_factor_std", MAX_IMU_SCALE_FACTOR_STD, " (10 %)"),
                ("gyro_scale_factor_std", MAX_IMU_SCALE_FACTOR_STD, " (10 %)"),
                ("accel_misalignment_std", MAX_IMU_MISALIGNMENT_STD, " rad"),
                ("gyro_misalignment_std", MAX_IMU_MISALIGNMENT_STD, " rad"),
                ("gyro_g_sensitivity_std", MAX_GYRO_G_SENSITIVITY_STD, " rad/s per m/s^2")):
            _check(getattr(self, name) <= bound, f"imu.{name}",
                   f"a std of at most {bound:g}{unit}", getattr(self, name))

    @property
    def accel_tau(self) -> float:
        """The accelerometers' Gauss-Markov correlation time, s."""
        tau = self.accel_bias_correlation_time
        return self.bias_correlation_time if tau is None else tau

    @property
    def gyro_tau(self) -> float:
        """The gyroscopes' Gauss-Markov correlation time, s."""
        tau = self.gyro_bias_correlation_time
        return self.bias_correlation_time if tau is None else tau


_IMU_OPTIONAL = ("accel_bias_correlation_time", "gyro_bias_correlation_time")
_IMU_VIBRATION = ("accel_vibration_std", "gyro_vibration_std", "accel_vibration_per_rate",
                  "gyro_vibration_per_rate")


@dataclass(frozen=True)
class DepthConfig:
    """A pressure depth sensor at the body origin, per sample k:
    ``depth[k] = resolution * round((true[k] + bias + n[k]) / resolution)``,
    ``n[k] ~ N(0, noise_std^2)``; bias is drawn per mission, ``N(0, bias_std^2)``, and
    stored in its attributes; ``resolution`` 0 means no quantisation.

    Attributes:
        rate_hz: sample rate; the IMU rate must be a whole multiple of it.
        noise_std: m, white noise per sample.
        bias_std: m, spread of the per-mission offset (the sensor's accuracy).
        resolution: m, quantisation step of the output (0: none).
    """

    rate_hz: float = 10.0
    noise_std: float = 0.0
    bias_std: float = 0.0
    resolution: float = 0.0

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            _finite(f"depth.{f.name}", getattr(self, f.name))
            _check(getattr(self, f.name) >= 0, f"depth.{f.name}", "a value >= 0",
                   getattr(self, f.name))
        _check(self.rate_hz > 0, "depth.rate_hz", "a positive rate in Hz", self.rate_hz)


# The water section. Correlation times must span several grid steps of the paths that
# carry them (``auvsim.physics.water``: 10 s for the current, 0.1 s for the disturbances), so the
# interpolated path is the Gauss-Markov process and not the grid's straight lines.
MIN_CURRENT_TIME = 60.0  # s
MIN_DISTURBANCE_TIME = 0.5  # s
# A slow spatial variation is long against the vehicle and the ~400 m a block covers; at
# most the 1000 km of an ocean basin's gyre.
MIN_WAVELENGTH, MAX_WAVELENGTH = 100.0, 1e6  # m
# Turbulent forces and moments: at most 1 kN (N m), like the net buoyancy: 14 % of the
# A18-D's weight, a hundred times what a few cm/s of turbulence exert (presets.navigator).
MAX_TURBULENCE = 1000.0  # N, N m
MAX_RPM_JITTER = 100.0  # rpm: 10 % of the shipped shaft speeds' ~1000 rpm class
MAX_FIN_JITTER_DEG = 5.0  # deg: a third of the shipped fins' 15 deg travel


@dataclass(frozen=True)
class WaterConfig:
    """The moving water and the motion disturbances (``auvsim.physics.water`` has the model).
    Every default turns its effect off (still water, no disturbance).

    Current: a mission's surface speed is drawn uniformly in [``speed_min``,
    ``speed_max``] and its direction (where the water flows TOWARD, deg from north)
    uniformly in ``direction_deg`` +/- ``direction_spread_deg``; both vary in time as
    Gauss-Markov processes (``speed_std``/``speed_time``, ``direction_std_deg``/
    ``direction_time``), and in space by ``spatial_std`` over ``spatial_wavelength``. The
    depth law scales all of it: ``power`` (f = ((H - z) / H) ** ``power_exponent``, H =
    ``water_depth``, or the seafloor's ``depth`` when None) or ``piecewise`` (factors
    ``profile_factors`` at depths ``profile_depths``, linear between, constant beyond).
    Added to ``vehicle.current_ned``.

    Disturbances: a turbulent wrench in body axes (``turbulence_force_std`` N and
    ``turbulence_moment_std`` N m per FRD axis, correlation ``turbulence_time``) and
    jitter of the shaft speed (``rpm_jitter_std``) and of the rudder and stern planes
    (``fin_jitter_std_deg``), correlation ``jitter_time``; all Gauss-Markov.

    Bounds: speeds and their stds at most ``MAX_CURRENT`` (3 m/s, also for the drawn
    speed plus three stds of each variation); correlation times of at least
    ``MIN_CURRENT_TIME`` (60 s) and ``MIN_DISTURBANCE_TIME`` (0.5 s); wavelengths in
    [100 m, 1000 km]; profile factors in [-1, 1] (relative to the surface: a layer may
    flow against it, as an estuary's bottom water does); turbulence up to 1 kN (N m),
    jitter up to 100 rpm and 5 deg.
    """

    speed_min: float = 0.0
    speed_max: float = 0.0
    direction_deg: float = 0.0
    direction_spread_deg: float = 0.0
    speed_std: float = 0.0
    speed_time: float = 3600.0
    direction_std_deg: float = 0.0
    direction_time: float = 3600.0
    spatial_std: float = 0.0
    spatial_wavelength: float = 5000.0
    profile: str = "power"
    power_exponent: float = 1.0 / 7.0
    water_depth: float | None = None
    profile_depths: tuple[float, ...] = (0.0,)
    profile_factors: tuple[float, ...] = (1.0,)
    turbulence_force_std: tuple[float, float, float] = (0.0, 0.0, 0.0)
    turbulence_moment_std: tuple[float, float, float] = (0.0, 0.0, 0.0)
    turbulence_time: float = 3.0
    rpm_jitter_std: float = 0.0
    fin_jitter_std_deg: float = 0.0
    jitter_time: float = 1.0

    def __post_init__(self) -> None:
        scalars = ("speed_min", "speed_max", "direction_deg", "direction_spread_deg",
                   "speed_std", "speed_time", "direction_std_deg", "direction_time",
                   "spatial_std", "spatial_wavelength", "power_exponent", "turbulence_time",
                   "rpm_jitter_std", "fin_jitter_std_deg", "jitter_time")
        for name in scalars:
            _finite(f"water.{name}", getattr(self, name))
        for name in ("speed_min", "speed_max", "speed_std", "spatial_std"):
            _check(0 <= getattr(self, name) <= MAX_CURRENT, f"water.{name}",
                   f"a speed in [0, {MAX_CURRENT:g}] m/s", getattr(self, name))
        _check(self.speed_min <= self.speed_max, "water.speed_min",
               f"at most speed_max ({self.speed_max:g} m/s)", self.speed_min)
        worst = self.speed_max + 3.0 * (self.speed_std + self.spatial_std)
        _check(worst <= MAX_CURRENT, "water.speed_max",
               f"a current of at most {MAX_CURRENT:g} m/s with three stds of speed_std and "
               f"spatial_std (the strongest ocean currents are about 2.5 m/s)",
               f"{self.speed_max:g} + 3 x ({self.speed_std:g} + {self.spatial_std:g}) m/s")
        _angle("water.direction_deg", self.direction_deg)
        for name in ("direction_spread_deg", "direction_std_deg"):
            _check(0 <= getattr(self, name) <= 180, f"water.{name}", "an angle in [0, 180] deg",
                   getattr(self, name))
        for name in ("speed_time", "direction_time"):
            _check(getattr(self, name) >= MIN_CURRENT_TIME, f"water.{name}",
                   f"a correlation time of at least {MIN_CURRENT_TIME:g} s", getattr(self, name))
        for name in ("turbulence_time", "jitter_time"):
            _check(getattr(self, name) >= MIN_DISTURBANCE_TIME, f"water.{name}",
                   f"a correlation time of at least {MIN_DISTURBANCE_TIME:g} s",
                   getattr(self, name))
        _check(MIN_WAVELENGTH <= self.spatial_wavelength <= MAX_WAVELENGTH,
               "water.spatial_wavelength",
               f"a length in [{MIN_WAVELENGTH:g}, {MAX_WAVELENGTH:g}] m", self.spatial_wavelength)
        _check(isinstance(self.profile, str) and self.profile in ("power", "piecewise"),
               "water.profile", "power or piecewise", self.profile)
        _check(0 <= self.power_exponent <= 1, "water.power_exponent",
               "an exponent in [0, 1] (1/7 for a bottom boundary layer)", self.power_exponent)
        if self.water_depth is not None:
            _finite("water.water_depth", self.water_depth)
            _check(0 < self.water_depth <= MAX_DEPTH, "water.water_depth",
                   f"a depth in (0, {MAX_DEPTH:g}] m", self.water_depth)
        depths = _series("water.profile_depths", self.profile_depths)
        factors = _series("water.profile_factors", self.profile_factors)
        object.__setattr__(self, "profile_depths", depths)
        object.__setattr__(self, "profile_factors", factors)
        _check(all(0 <= d <= MAX_DEPTH for d in depths)
               and all(b > a for a, b in zip(depths[:-1], depths[1:], strict=True)),
               "water.profile_depths",
               f"increasing depths in [0, {MAX_DEPTH:g}] m", depths)
        _check(len(factors) == len(depths), "water.profile_factors",
               f"one factor per profile depth ({len(depths)})", factors)
        _check(all(-1 <= f <= 1 for f in factors), "water.profile_factors",
               "factors in [-1, 1] of the surface current", factors)
        for name, most, unit in (("turbulence_force_std", MAX_TURBULENCE, "N"),
                                 ("turbulence_moment_std", MAX_TURBULENCE, "N m")):
            value = _vector(f"water.{name}", getattr(self, name), 3)
            object.__setattr__(self, name, value)
            _check(all(0 <= v <= most for v in value), f"water.{name}",
                   f"three stds in [0, {most:g}] {unit}", value)
        _check(0 <= self.rpm_jitter_std <= MAX_RPM_JITTER, "water.rpm_jitter_std",
               f"a std in [0, {MAX_RPM_JITTER:g}] rpm", self.rpm_jitter_std)
        _check(0 <= self.fin_jitter_std_deg <= MAX_FIN_JITTER_DEG, "water.fin_jitter_std_deg",
               f"a std in [0, {MAX_FIN_JITTER_DEG:g}] deg", self.fin_jitter_std_deg)


@dataclass(frozen=True)
class LocationConfig:
    """Where on the Earth the missions are flown: the geographic origin of the local NED
    frame (the point north 0, east 0 on the sea surface). Both or neither.

    Without it (the default) the world is auvsim's flat one that does not rotate, with the
    vehicle model's gravity (9.81 m/s^2 in ``models/auv.xml``): every dataset made before
    it is unchanged. With it the vehicle's motion (MuJoCo's, unchanged) is read as motion
    over an Earth that rotates (WGS-84, ``auvsim.physics.earth``), and what an inertial
    sensor measures follows, at the origin's latitude:

    - the gyros read ``w_ib = w_nb + C^T w_ie``: the body's rate in the local frame
      (``truth/angular_rate``) plus the Earth's rate (15.04 deg/h: north
      ``Omega cos(lat)``, down ``-Omega sin(lat)``) in body axes;
    - the accelerometers read ``f = C^T (a + 2 w_ie x v - g_n)``, ``g_n`` the WGS-84
      normal gravity at the latitude and the IMU's depth (``normal_gravity(lat,
      -depth)``) instead of the model's gravity, with the Coriolis term of the frame's
      rotation (v the IMU's NED velocity); ``truth/specific_force`` is this ideal reading.

    A dataset's missions share one place, as they share the seafloor and the water; each
    mission records it (attributes ``latitude_deg``, ``longitude_deg``, and ``gravity``
    the normal gravity at the origin). The longitude changes nothing measured (the normal
    gravity and the Earth's rate depend on the latitude alone); it places the missions on
    a map.

    Attributes:
        latitude_deg: geodetic latitude, deg in [-90, 90] (north positive); None: none.
        longitude_deg: longitude, deg in [-180, 180] (east positive); None: none.
    """

    latitude_deg: float | None = None
    longitude_deg: float | None = None

    def __post_init__(self) -> None:
        for name, most in (("latitude_deg", 90.0), ("longitude_deg", 180.0)):
            value = getattr(self, name)
            if value is None:
                continue
            _finite(f"location.{name}", value)
            _check(abs(value) <= most, f"location.{name}",
                   f"deg in [-{most:g}, {most:g}]", value)
        _check((self.latitude_deg is None) == (self.longitude_deg is None),
               "location", "both latitude_deg and longitude_deg, or neither",
               dataclasses.asdict(self))

    @property
    def given(self) -> bool:
        """Whether the missions have a geographic origin (else: the flat world)."""
        return self.latitude_deg is not None


@dataclass(frozen=True)
class Config:
    """Everything that determines a dataset.

    Attributes:
        vehicle: the vehicle and the water.
        missions: the missions, each simulated independently from its own seed; at most
            ``MAX_MISSIONS`` (1000) lasting ``MAX_TOTAL_DURATION`` (30 days) in all.
        seafloor: the terrain under every mission.
        dvl: the DVL and its error model.
        imu: the IMU and its error model; its rate is the rate of the truth group, and the
            physics rate must be a whole multiple of it.
        depth: the pressure depth sensor and its error model.
        water: the current and the motion disturbances (default: still water, none).
        compression: HDF5 compression, ``lzf`` (fast) or ``gzip`` (read by every HDF5 tool).
        location: where on the Earth the missions are flown (``LocationConfig``; default:
            nowhere, the flat world that does not rotate).
    """

    vehicle: VehicleConfig = field(default_factory=VehicleConfig)
    missions: tuple[MissionConfig, ...] = (MissionConfig(),)
    seafloor: SeafloorConfig = field(default_factory=SeafloorConfig)
    dvl: DvlConfig = field(default_factory=DvlConfig)
    imu: ImuConfig = field(default_factory=ImuConfig)
    depth: DepthConfig = field(default_factory=DepthConfig)
    compression: str = "lzf"
    water: WaterConfig = field(default_factory=WaterConfig)
    location: LocationConfig = field(default_factory=LocationConfig)

    def __post_init__(self) -> None:
        object.__setattr__(self, "missions", tuple(self.missions))
        _check(len(self.missions) > 0, "missions", "at least one mission", self.missions)
        kinds = sorted({type(m).__name__ for m in self.missions
                        if not isinstance(m, MissionConfig)})
        _check(not kinds, "missions", "MissionConfigs (MissionConfig(scenario=ScenarioConfig"
               "(...)), each with a name and a seed)", ", ".join(kinds))
        if len(self.missions) > MAX_MISSIONS:
            raise ConfigError(f"missions: expected at most {MAX_MISSIONS} missions (make "
                              f"several datasets), got {len(self.missions)}")
        total = sum(m.scenario.duration for m in self.missions)
        if total > MAX_TOTAL_DURATION:
            raise ConfigError(f"missions: expected at most {MAX_TOTAL_DURATION:g} s (30 days) "
                              f"of missions in all (make several datasets), got {total:g} s")
        names = [m.name for m in self.missions]
        _check(len(set(names)) == len(names), "missions", "distinct mission names", names)
        _check(self.compression in ("lzf", "gzip"), "compression", "lzf or gzip",
               self.compression)
        for sensor in registry().values():  # each plugin's checks against the others
            sensor.check(self)
        # A heightmap's and a grid's depth is the terrain's own, not seafloor.depth.
        if self.seafloor.kind not in ("heightmap", "grid"):
            for m in self.missions:
                _check(m.scenario.depth < self.seafloor.depth, "depth",
                       f"a depth above the seafloor at {self.seafloor.depth:g} m",
                       m.scenario.depth)
        w = self.water
        moving = w.speed_max > 0 or w.speed_std > 0 or w.spatial_std > 0
        # The power law's H defaults to the seafloor plane's depth; a heightmap has none.
        _check(not (moving and w.profile == "power" and w.water_depth is None
                    and self.seafloor.kind in ("heightmap", "grid")), "water.water_depth",
               "the water depth H of the power law (over a heightmap or a grid the seafloor "
               "gives no single depth)", w.water_depth)
        _check(self.seafloor.kind != "grid" or self.location.given, "location",
               "latitude_deg and longitude_deg, which place the missions on seafloor.grid",
               dataclasses.asdict(self.location))
        if moving:  # the constant current and the water's own, together
            worst = (math.hypot(*self.vehicle.current_ned) + w.speed_max
                     + 3.0 * (w.speed_std + w.spatial_std))
            _check(worst <= MAX_CURRENT, "water.speed_max",
                   f"a current of at most {MAX_CURRENT:g} m/s with vehicle.current_ned added "
                   "(the strongest ocean currents are about 2.5 m/s)",
                   f"{worst:.4g} m/s in all")

    def with_duration(self, duration: float) -> Config:
        """The same config with every mission lasting ``duration`` s."""
        return dataclasses.replace(self, missions=tuple(
            dataclasses.replace(m, scenario=dataclasses.replace(m.scenario, duration=duration))
            for m in self.missions))

    def to_json(self) -> str:
        return json.dumps(dataclasses.asdict(self), sort_keys=True)

    @classmethod
    def from_dict(cls, d: dict) -> Config:
        """Build from nested dicts (parsed JSON or TOML); unknown keys are an error."""
        return _from_dict(cls, d, "config")

    @classmethod
    def from_json(cls, text: str) -> Config:
        return cls.from_dict(json.loads(text))


# The sections of each config class, from its fields' types (a new sensor's section is a
# dataclass here and a field of Config, nothing more).
_NESTED = {(cls, f.name): globals()[f.type]
           for cls in (Config, MissionConfig) for f in dataclasses.fields(cls)
           if dataclasses.is_dataclass(globals().get(f.type))}


def _from_dict(cls, d, path: str):
    if not isinstance(d, dict):
        raise ConfigError(f"{path}: expected a table of settings, got {d!r}")
    known = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(d) - known)
    if unknown:
        raise ConfigError(f"{path}: unknown setting(s) {', '.join(unknown)}"
                          f"{did_you_mean(unknown[0], known)}; expected some of "
                          f"{', '.join(sorted(known))}")
    kwargs = {}
    for key, value in d.items():
        if cls is Config and key == "missions":
            if not isinstance(value, (list, tuple)):
                raise ConfigError(f"{path}.missions: expected a list of missions, got {value!r}")
            kwargs[key] = tuple(_mission_from_dict(m, f"{path}.missions[{i}]")
                                for i, m in enumerate(value))
        elif (cls, key) in _NESTED:
            kwargs[key] = _from_dict(_NESTED[cls, key], value, f"{path}.{key}")
        else:
            kwargs[key] = tuple(value) if isinstance(value, list) else value
    return cls(**kwargs)


def _mission_from_dict(d, path: str) -> MissionConfig:
    """A mission's settings, whose errors say which mission (of several in a file)."""
    try:
        return _from_dict(MissionConfig, d, path)
    except ConfigError as e:
        if str(e).startswith(path):
            raise
        name = d.get("name") if isinstance(d, dict) else None
        raise ConfigError(f"{path}" + (f" ({name!r})" if isinstance(name, str) else "")
                          + f": {e}") from None


def _series(name: str, value) -> tuple[float, ...]:
    """1 to 1000 finite numbers, as a tuple."""
    n = len(value) if isinstance(value, (list, tuple)) else 0
    _check(1 <= n <= 1000, name, "a list of 1 to 1000 numbers", value)
    return _vector(name, value, n)


def _vector(name: str, value, n: int) -> tuple[float, ...]:
    try:
        if isinstance(value, str) or any(isinstance(v, (bool, str)) for v in value):
            raise TypeError
        out = tuple(float(v) for v in value)
    except (TypeError, ValueError, OverflowError):
        out = ()
    _check(len(out) == n and all(math.isfinite(v) for v in out), name,
           f"{n} finite numbers", value)
    return out


def load_config(config: str | os.PathLike) -> Config:
    """The ``Config`` of a TOML file (what ``auvsim generate --config`` reads): a heightmap
    or grid it names is found next to the file.

    Raises:
        ConfigError: the file is missing, unreadable or not TOML, or a setting is wrong
            (one line each).
    """
    import sys
    from pathlib import Path

    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib
    path = Path(config)
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except FileNotFoundError:
        raise ConfigError(f"{str(path)!r}: no such file", argument="config") from None
    except OSError as e:
        raise ConfigError(f"{str(path)!r}: cannot read it ({e.strerror})",
                          argument="config") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise ConfigError(f"{str(path)!r}: not valid TOML ({e})", argument="config") from None
    except RecursionError:  # the parser recurses once per level of arrays or tables
        raise ConfigError(f"{str(path)!r}: not valid TOML (arrays or tables nested too "
                          "deeply to read)", argument="config") from None
    floor = data.get("seafloor")
    for key, what in (("heightmap", "a .npy file"), ("grid", "a GeoTIFF or NetCDF file")):
        if not (isinstance(floor, dict) and isinstance(floor.get(key), str)):
            continue
        # A heightmap or grid named in a config file is found next to that file.
        try:
            floor[key] = str((path.parent / Path(floor[key]).expanduser()).resolve())
        except (RuntimeError, ValueError, OSError) as e:  # ~nobody, a NUL byte, a loop
            raise ConfigError(f"seafloor.{key}: expected a path to {what}, got "
                              f"{floor[key][:200]!r} ({e})") from None
    try:
        return Config.from_dict(data)
    except RecursionError:  # a deep value in a field that Python walks (its repr, say)
        raise ConfigError(f"{str(path)!r}: a setting is arrays or tables nested too deeply "
                          "to read", argument="config") from None
