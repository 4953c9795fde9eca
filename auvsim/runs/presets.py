"""Named configurations. A preset is a ``Config``, not a code path: ``auvsim generate
--preset NAME`` simulates exactly what it returns (scenario flags may override)."""

from __future__ import annotations

import dataclasses
import math

from auvsim.checks import did_you_mean
from auvsim.config import (
    MAX_DURATION,  # noqa: F401  (re-exported for the experiments that size presets)
    Config,
    DepthConfig,
    DvlConfig,
    LocationConfig,
    MissionConfig,
    ScenarioConfig,
    SeafloorConfig,
    VehicleConfig,
    WaterConfig,
)
from auvsim.errors import ConfigError
from auvsim.physics.maneuvers import Lawnmower, SpiralDive
from auvsim.physics.maneuvers import missions as maneuver_missions
from auvsim.sensors.dvl import NAVIGATOR_SLOW_ERROR_STD, NAVIGATOR_SLOW_ERROR_TIME
from auvsim.sensors.imu import IMU_GRADES

# The BeamsNet paper's simulation (sec. 4.1) as its published code ran it: straight lines
# at 1, 2 and 3 m/s for 7,200 s each, DVL 1 Hz, IMU 100 Hz, one scale factor of 0.7 % and a
# bias of 0.0001 m/s on all beams, 20 deg beams, and beam noise of 0.042**2 m/s (the text
# says 0.042 m/s): ../shared/reference/beamsnet-reference.md.
PAPER_NOISE_CODE = 0.042**2
PAPER_NOISE_TEXT = 0.042


def _paper(noise_std: float) -> Config:
    missions = tuple(
        MissionConfig(name=f"speed_{v}", seed=v,
                      scenario=ScenarioConfig(speed=float(v), heading_deg=0.0, depth=20.0,
                                              duration=7200.0))
        for v in (1, 2, 3))
    return Config(
        missions=missions,
        seafloor=SeafloorConfig(kind="flat", depth=60.0),
        dvl=DvlConfig(rate_hz=1.0, beam_angle_deg=20.0, min_range=0.7, max_range=200.0,
                      scale_factor=0.007, bias=0.0001, noise_std=noise_std),
        # The paper does not state its IMU; the Snapir carries a Phins-class unit.
        imu=IMU_GRADES["navigation"],
    )


# The manoeuvres of the stress test, each 10 minutes at 2 m/s from 20 m depth: every
# manoeuvre of auvsim.physics.maneuvers and its variants (the straight line first, for reference).
MANEUVER_MISSIONS = tuple(maneuver_missions())


def maneuvers(duration: float = 600.0, noise_std: float = PAPER_NOISE_CODE) -> Config:
    """Every manoeuvre once, with the paper-sim sensors (beam noise ``noise_std``, m/s: the
    paper's code by default, ``PAPER_NOISE_TEXT`` for its text's), so that models trained
    on the paper's straight lines can be tested on them (``beamsnet stress``)."""
    paper = _paper(noise_std)
    missions = tuple(
        MissionConfig(name=name, seed=100 + i, scenario=ScenarioConfig(
            name=kind, speed=2.0, heading_deg=0.0, depth=20.0, duration=duration,
            options=dict(options)))
        for i, (name, kind, options) in enumerate(MANEUVER_MISSIONS))
    return Config(missions=missions, seafloor=paper.seafloor, dvl=paper.dvl, imu=paper.imu)


# The navigator's water: the current over the Israeli shelf, where the Snapir flies (off
# Haifa), with the turbulence and actuator jitter a vehicle meets in it
# (auvsim.physics.water has the model, config.WaterConfig the settings).
# - Surface speed uniform in [0.05, 0.5] m/s, in any direction relative to the survey. The
#   shelf current off Israel is a wind- and circulation-driven alongshore flow, northward
#   throughout the year with maxima in winter and summer and in winter storms (Rosentraub &
#   Brenner 2007, JGR 112, C11001, "Circulation over the southeastern continental shelf
#   and slope of the Mediterranean Sea": from its abstract; its figures were not at hand);
#   a year of 16 current moorings in the south-east Mediterranean (Feb 1999 - Jan 2000)
#   saw at most 0.89 m/s, in winter storms (K. M. Tonbol, "Circulation patterns of south
#   east sector of the Mediterranean Sea", AAST abstract). The tide is weak there: its
#   current amplitudes are 1-2 cm/s (M2) to a few cm/s (K1, O1) at the DeepLev mooring
#   off Israel (Front. Mar. Sci. 2024, 10.3389/fmars.2024.1388137), so the floor is a few
#   cm/s, not slack water. The upper bound is MarLIN's "weak" flow (below 0.5 m/s,
#   marlin.ac.uk/glossary/waterflowrate), our choice for the days a survey is flown:
#   the storm flows near the year's maximum are the days it is not. (The previous
#   0.1-1 m/s was a tidal shelf's, 2.3 times the Snapir day's current: benchmarks/turning.py.)
# - Over depth the 1/7 power law of a bottom boundary layer filling the column
#   (Soulsby 1997, Dynamics of Marine Sands, ch. 3), over the seafloor's 60 m.
# - In time: the diurnal tide (K1, 23.93 h) of a few cm/s turns the flow over about a
#   quarter period, 6 h: speed and direction are Gauss-Markov with a 6 h correlation time,
#   0.03 m/s (the tide's amplitude) and 6 deg (that amplitude across the mean 0.275 m/s:
#   atan(0.03 / 0.275)).
# - In space: 0.05 m/s over 5 km, the submesoscale of coastal currents (0.1-10 km:
#   McWilliams 2016, Proc. R. Soc. A 472, 20160117); our choice of magnitude.
# - Turbulence: in a bottom boundary layer u' = 2.30 u* exp(-z/h), v' = 1.63 u* exp(-z/h),
#   w' = 1.27 u* exp(-z/h) (Nezu & Nakagawa 1993, Turbulence in Open-Channel Flows),
#   with u* = sqrt(C_D) U and C_D = 0.0025 (Soulsby 1997): at the mean current, U = 0.275
#   m/s, u* = 0.014 m/s and at mid-depth the fluctuations are 0.011-0.019 m/s; we take
#   0.0165 m/s (0.03 m/s at U = 0.5 m/s, scaled with U). Through the A18-D's force model
#   at 2 m/s (hydro.py's coefficients of models/auv.xml), linearised: surge 2 X_uu U u' =
#   2 x 11.08 x 2 x 0.0165 = 0.7 N (Prestero's axial drag, C_d 0.11); sway and heave (hull
#   lift 153.9 N s^2/m^2 and fin-pair lift 147.6 N s^2/m^2, each times U v') 5 + 5 = 10 N;
#   pitch and yaw, the same forces at the hull-lift centre (-1.32 m) and the fins
#   (-2.6 m), 19 N m; roll, one fin pair meeting opposite flows of an eddy smaller than
#   its span (each fin 74 x 2 x 0.0165 = 2.4 N, about 0.35 m from the axis), 1.7 N m.
#   Correlation time 3 s: an eddy of about a hull length (6 m) passed at 2 m/s; larger
#   ones are the slow current, smaller ones average out over the 5.5 m hull (our choice).
# - Jitter: 0.2 deg on the rudder and stern planes (a fin servo's deadband and position
#   sensing, a few tenths of a degree) and 2 rpm on the shaft (0.4 % at the 490 rpm of
#   2 m/s, a speed controller's ripple), correlated over 1 s: our choices, no datasheet
#   at hand gives them.
NAVIGATOR_WATER = WaterConfig(
    speed_min=0.05, speed_max=0.5, direction_deg=0.0, direction_spread_deg=180.0,
    speed_std=0.03, speed_time=21600.0, direction_std_deg=6.0, direction_time=21600.0,
    spatial_std=0.05, spatial_wavelength=5000.0, profile="power", power_exponent=1.0 / 7.0,
    turbulence_force_std=(0.7, 10.0, 10.0), turbulence_moment_std=(1.7, 19.0, 19.0),
    turbulence_time=3.0, rpm_jitter_std=2.0, fin_jitter_std_deg=0.2, jitter_time=1.0)


# The Snapir's waters: the Mediterranean off Haifa, where the shared real segments were
# recorded (../shared/data/snapir-akit/README.md); the first point of Trajectory1's
# reference, GT_trajectory1.csv, is at 32.8498 N, 34.8922 E (its six segments start within
# 32.8498-32.8582 N, 34.8922-34.9350 E). There the WGS-84 normal gravity is 9.7955 m/s^2,
# the mean |f| the issue found in the data on quiet stretches, and the Earth's rate has a
# north component of 12.64 deg/h and a down one of -8.16 deg/h.
SNAPIR_WATERS = LocationConfig(latitude_deg=32.8498, longitude_deg=34.8922)


# How a real survey AUV flies, for the presets that mean to look like its logs:
# - It commands propeller rpm from a speed table and lets the speed drop in a turn (the
#   Snapir's hard turns lose 29 % of their speed, median of 21: benchmarks/turning.py),
#   where auvsim's speed loop would raise the rpm and hold it: ``speed_control="rpm"``.
# - It turns at the end of a line at full rudder (the Snapir's hard turns peak at 16.5
#   deg/s, median of 21, where the A18-D's full-rudder step peaks at 15.0), where the
#   heading PID's yaw-rate term backs the rudder off from the start of the turn (peaks
#   of 12.4 deg/s in the survey turns: benchmarks/turning.py --rpm-alone):
#   ``heading_control="full-rudder-turns"`` holds full rudder up to the PID's own braking
#   point and hands over to the PID there.
# - Its IMU and DVL sit where the Snapir's do, not at the A18-D model's generic sites (0.5
#   and 1.0 m forward of the centre of buoyancy). ``auvsim check-log`` measures them on
#   each of the six real segments (reports/sea.md, "dvl lever arm", "imu lever arm"; least
#   squares on the velocity and specific-force differences in turns), from the
#   reference's point, within 0.1 m of one another in x: the medians, DVL (-1.85, -0.03,
#   +0.13) m and IMU (-1.77, -0.01, -0.14) m FRD, both 1.8 m aft, the IMU 0.27 m above
#   the DVL. That point is taken as the model's origin: at the hard turns' yaw-rate peak
#   the reference's sideslip (medians of 21: 0.30 m/s at 16.5 deg/s) puts the hull's
#   pivot point 1.04 m ahead of it, and the model's sideslip (0.29 m/s at 15.0 deg/s,
#   models/README.md) puts it 1.11 m ahead of the origin: the two points agree within
#   about 0.1 m. A DVL aft of the pivot sees the turn's r x more sway; at 1.0 m forward
#   it saw less.
SNAPIR_IMU_POSITION = (-1.77, -0.01, -0.14)  # m, FRD from the body origin
SNAPIR_DVL_POSITION = (-1.85, -0.03, 0.13)  # m, FRD from the body origin
REAL_VEHICLE = VehicleConfig(speed_control="rpm", heading_control="full-rudder-turns",
                             imu_position=SNAPIR_IMU_POSITION,
                             dvl_position=SNAPIR_DVL_POSITION)
# - It flies parallel survey lines joined by turns at their ends (the lawnmower pattern
#   of bathymetric and side-scan surveys), and a depth, speed or straight-line test on a
#   survey is flown along those lines, not on one endless heading: the lawnmower's own
#   300 m legs and 50 m spacing.
SURVEY_LINES = {"leg_m": Lawnmower.Options.leg_m, "spacing_m": Lawnmower.Options.spacing_m}
# - A turning trial turns about two circles and then goes on with the mission: the
#   rudder is held for TURN_TRACK_M of track (two circles of the A18-D's 88 m at 15 deg
#   of rudder, measured at 2 m/s; the radius barely depends on speed), i.e. TURN_TRACK_M /
#   speed seconds, then the vehicle returns to its heading. A spiral dive turns while it
#   dives (dive_m / descent_rate) and then flies level.
TURN_TRACK_M = 180.0


def _as_flown(kind: str, speed: float, options: dict) -> dict:
    """A manoeuvre's options as a real survey vehicle flies it (``SURVEY_LINES``,
    ``TURN_TRACK_M``): the options of ``maneuvers`` with the legs or the end of the turn."""
    if kind in ("straight", "depth_steps", "yoyo", "speed_steps"):
        return {**SURVEY_LINES, **options}
    if kind == "turning_circle":
        return {"turn_s": TURN_TRACK_M / speed, **options}
    if kind == "spiral_dive":
        o = SpiralDive.Options(**options)
        return {"turn_s": o.dive_m / o.descent_rate, **options}
    return dict(options)


# The vibration the Snapir's iXblue Phins records in its hull, measured on the six A-KIT
# segments (Cohen & Klein 2025; ``benchmarks/imu_spectrum.py`` prints it): the r.m.s. above
# 10 Hz over each second grows with its mean |yaw rate| (correlation 0.84 to 0.91 per
# segment), from 6 to 10 mm/s^2 in straight flight to about 100 in the hardest turns, and
# a least-squares line over the segments' seconds gives per axis (x, y, z) 8.6 / 10.1 /
# 6.3 mm/s^2 + 183 / 345 / 355 mm/s^2 per rad/s of |r| (r^2 0.62 to 0.75) and 83 / 32 /
# 23 deg/h + 1037 / 1570 / 390 deg/h per rad/s (r^2 0.63 to 0.69), against the datasheet
# grade's white noise of 1.7 mm/s^2 and 1.3 to 1.8 deg/h there (the real sensor's own
# white noise is in the intercepts, and the grade adds its own: 2 to 4 % more in
# quadrature). Most of the accelerometers' power lies in a line at 24 Hz on every segment,
# whatever the speed (23.7 Hz at 1.6 m/s, 24.8 at 2.1); its cause (the fins at full
# deflection, the actuators) is not in the logs. It integrates away: the IMU's velocity
# change over 1 s matches the DVL's to within the DVL's own noise (``benchmarks/
# dvl_error.py``), so the model is a vibration with no power at zero frequency
# (``auvsim.sensors.imu``), not white noise.
_DEG_PER_HOUR = math.pi / 180.0 / 3600.0  # rad/s
SNAPIR_VIBRATION = dict(
    accel_vibration_std=(0.0086, 0.0101, 0.0063),
    accel_vibration_per_rate=(0.183, 0.345, 0.355),
    gyro_vibration_std=tuple(x * _DEG_PER_HOUR for x in (82.8, 32.1, 23.3)),
    gyro_vibration_per_rate=tuple(x * _DEG_PER_HOUR for x in (1036.9, 1570.1, 390.1)))


def navigator() -> Config:
    """A physical default: a Teledyne RDI Workhorse Navigator-like DVL (600 kHz) on the
    A18-D over gently rough terrain, with a navigation-grade IMU, flying survey lines
    (``SURVEY_LINES``) at a held shaft speed, with its IMU and DVL where the Snapir's sit
    (``REAL_VEHICLE``), in the shelf current (``NAVIGATOR_WATER``).

    Figures of the Teledyne RDI Workhorse Navigator (its published specification): 30 deg
    Janus beams; bottom track about 0.7 to 90 m; long-term accuracy about 0.2 % of speed
    +/- 1 mm/s (taken here as the per-mission spread of the scale factor and bias;
    ../shared/reference/sensors.md). 1 Hz as in the paper's data. The terrain (1 m
    roughness, 25 m features, 60 m deep) is our choice. The range is each beam's slant
    range, as sensors.md has a beam lock only where it meets the floor within range; were
    the 90 m an altitude, as DVL datasheets often quote it, this DVL would lose lock early,
    at 90 cos 30 = 78 m over a flat floor (the 60 m floor keeps every mission far inside
    either).

    Its velocity error, split into what one ping adds and what survives averaging
    (``benchmarks/dvl_error.py`` prints the figures):

    - White beam noise, per beam and ping, is what the error velocity shows. The Snapir's
      own Navigator reports an error velocity of std 4.9 mm/s (robust std 4.4 mm/s) over
      15,393 valid pings of the MissBeamNet logs (Yona & Klein 2024), white (lag-1
      autocorrelation 0.09), growing with speed (2.0 mm/s below 0.5 m/s, 5.2 at 1.8-2.2
      m/s, 5.6 above) and not with altitude (5.6 mm/s at 10-20 m, 3.1 at 45-60 m). With
      auvsim's error velocity ``e = (y1 + y3 - y2 - y4) / (2 sqrt(2) sin(alpha))`` (RDI's
      scaling) white beam noise sigma gives ``std(e) = sigma / (sqrt(2) sin(alpha))`` =
      sqrt(2) sigma at 30 deg, the std of one horizontal component. The line through the
      logs' speed bins, std(e) = 1.6 mm/s + 1.7 mm/s per m/s, so gives sigma = 1.2 mm/s +
      1.2 mm/s per m/s of speed, with no range term: 5.1 mm/s of e at 2 m/s.
    - The slower errors the beams share do not show in the error velocity: the
      per-mission scale factor, bias, sound speed and misalignment below, and a
      time-correlated velocity error dv (Gauss-Markov, ``slow_error_std`` over
      ``slow_error_time``), measured on the Snapir's own Navigator in the six A-KIT
      segments (Cohen & Klein 2025, imported and corrected as ``beamsnet reproduce sea``
      does). The DVL's velocity minus the reference's, moved to the DVL, has an
      autocovariance (both horizontal axes pooled, each segment's mean removed) that drops
      from 112 to 69 (mm/s)^2 between lags 0 and 1 s (the white noise of both) and then
      decays: c(k) = sigma^2 exp(-k / tau) through lags 1-20 s gives sigma = 9.0 mm/s and
      tau = 18.8 s, so 9 mm/s over 19 s. That difference holds the reference's own slow
      errors too: an upper bound. The fit is itself biased low by each segment's mean
      removed (on known Gauss-Markov series of this length, by 5 % in sigma and 22 % in
      tau, with a scatter of 0.4 mm/s and 2.3 s: ``tests/test_dvl_noise.py``), so the data
      also allow about 9.5 mm/s over 24 s; the preset keeps the direct fit. The IMU, which
      no DVL error enters, checks it: the DVL's change of NED velocity over k s minus the
      IMU's integral of its specific force has an rms of 7.0, 7.2 and 7.6 mm/s per
      horizontal axis at k = 1, 2 and 3 s, where white noise of 5.1 mm/s with this slow
      error predicts 7.8, 8.3 and 8.7 (the IMU's own drift only adds). The 18 mm/s over
      3 s this preset had before (the rest of the publication's 0.02 m/s after the white
      noise, over a correlation time measured on the DVL-minus-reference difference by
      -1/ln r(1), which the white noise of the reference shortens) predicts 15.3, 19.2 and
      21.5: two to three times what the IMU sees. Averaged over T >> tau, dv leaves
      9 mm/s sqrt(2 tau / T), 0.9 mm/s over an hour, within the Navigator's long-term
      accuracy (0.2 % +/- 1 mm/s); in dead reckoning over 400 s it adds 9 mm/s
      sqrt(2 tau T) = 1.1 m per axis, below the 1.78 m median final error of the six real
      segments' DVL dead reckoning with the reference's attitude (``reports/sea.md``). Per
      axis at 2 m/s the error then totals sqrt(5.1^2 + 2^2 + 6^2 + 1.4^2 + 9^2) = 12.2
      mm/s, below the velocity std of 0.02 m/s the A-KIT publication states for this DVL
      (``../shared/reference/sensors.md``), a single figure that says nothing of how its
      error splits in time.

    The DVL loses lock and errs as an instrument does (``DvlConfig``):

    - Echoes fade near the rated range: lost with probability 1/2 at 80 m of slant range
      over a 4 m width (15 % at 73 m, 92 % at 90 m), our choice of a curve that ends at the
      rated 90 m.
    - Grazing loss from 60 deg of incidence (3 deg width): bottom backscatter falls as
      Lambert's law, cos^2 of the incidence angle (Urick, Principles of Underwater Sound,
      3rd ed., 1983, ch. 8), so a beam at 60 deg returns 4.8 dB less than at the 30 deg of
      level flight over a flat bottom; the threshold is our choice.
    - Dropouts: 2 % of beam-pings in bursts of 3 pings on average, 0.5 % of whole pings
      lost, one beam (index 2, the third) dead from 300 to 360 s and a soft bottom from 450 to 480 s
      (lock lost on every beam): our choices, so that every default mission shows each
      kind of loss.
    - Beam noise grows with speed as the real error velocity does (above); the real logs
      show no growth with range, so there is no range term.
    - Outliers: 0.2 % of beam-pings, Student t of std 0.3 m/s (our choice: the spikes of
      tenths of a m/s a real log shows).
    - Sound speed: a spread of 0.3 % of c_true / c_assumed. By Medwin's formula, which
      Teledyne RDI's ADCP manuals use (c = 1449.2 + 4.6 T - 0.055 T^2 + 0.00029 T^3 +
      (1.34 - 0.01 T)(S - 35) + 0.016 z), at 10 deg C the sound speed changes by 1.24 m/s
      per psu and 3.6 m/s per deg C: a DVL that measures its temperature but assumes
      35 psu is 0.3 % off (4.3 m/s) in 31.5 psu water. The measured beams are divided by
      the ratio, as RDI's correction multiplies them by it (Teledyne RDI, "ADCP
      Coordinate Transformation", P/N 951-6079-00, 2010, sec. 4.1).
    - Misalignment: 0.1 deg per axis, our choice of a residual after a careful
      installation.
    - Water track, when bottom lock is lost, on a layer 10 m below the DVL (RDI DVLs
      place the water-mass layer by command, BL), with 0.05 m/s of beam noise: our
      choice, worse than bottom track because the water's scatterers echo more weakly.

    The depth sensor is a KELLER Series 36 Xi W class transmitter with a 20 bar range
    (about 200 m, enough for this floor): its datasheet gives an accuracy of 0.02 %FS
    (4 mbar, 0.04 m of sea water at 9.94 m/bar; taken as the per-mission offset's spread)
    and a resolution of 5 ppm FS (0.1 mbar, 1 mm). Its noise (2 mm, two resolution steps)
    and its 10 Hz rate are our assumptions: the datasheet gives neither.

    The missions are flown in the Snapir's waters off Haifa (``SNAPIR_WATERS``), so the
    IMU measures the Earth's rate and the WGS-84 normal gravity there, as the real logs'
    IMU does (``auvsim.config.LocationConfig``).

    The IMU is the ``navigation-full`` grade on the Snapir's hull: it records the hull's
    vibration (``SNAPIR_VIBRATION``), which the grade's datasheet figures leave out.
    """
    return Config(
        missions=(MissionConfig(scenario=ScenarioConfig(options=dict(SURVEY_LINES))),),
        vehicle=REAL_VEHICLE,
        seafloor=SeafloorConfig(kind="procedural", depth=60.0, roughness=1.0,
                                correlation_length=25.0),
        dvl=DvlConfig(rate_hz=1.0, beam_angle_deg=30.0, min_range=0.7, max_range=90.0,
                      scale_factor_std=0.002, bias_std=0.001, noise_std=0.0012,
                      echo_loss_range=80.0, echo_loss_width=4.0, grazing_loss_angle_deg=60.0,
                      grazing_loss_width_deg=3.0, dropout_rate=0.02, dropout_burst=3.0,
                      ping_dropout_rate=0.005, beam_failures=((2, 300.0, 360.0),),
                      lock_loss_intervals=((450.0, 480.0),), noise_range_coeff=0.0,
                      noise_speed_coeff=0.0012, outlier_rate=0.002, outlier_std=0.3,
                      sound_speed_std=0.003, misalignment_std_deg=0.1, water_track=True,
                      water_track_range=10.0, water_track_noise_std=0.05,
                      slow_error_std=NAVIGATOR_SLOW_ERROR_STD,
                      slow_error_time=NAVIGATOR_SLOW_ERROR_TIME),
        imu=dataclasses.replace(IMU_GRADES["navigation-full"], **SNAPIR_VIBRATION),
        depth=DepthConfig(rate_hz=10.0, noise_std=0.002, bias_std=0.04, resolution=0.001),
        water=NAVIGATOR_WATER,
        location=SNAPIR_WATERS,
    )


# The slow variant of each manoeuvre: 0.8 m/s (the speed steps between 1 and 0.5 m/s),
# inside the 0.5-1 m/s legs a real log holds and the training data of ``maneuvers`` never
# flew; 0.5 m/s is the slowest set point the autopilot holds depth at (vehicle.MIN_SPEED).
SLOW_SPEED = 0.8  # m/s
SLOW_OPTIONS = {"speed_steps": (1.0, {"low": 0.5})}


def realistic_maneuvers(duration: float = 600.0) -> Config:
    """The manoeuvre set flown as a real vehicle flies it: every manoeuvre of
    ``maneuvers`` at 2 m/s and again slowly (``SLOW_SPEED``), each in its own current,
    with the navigator's water, terrain, sensors (every DVL failure and error, the
    calibrated IMU errors) and vehicle (rpm held, ``REAL_VEHICLE``). Each mission draws its
    current from the navigator's distribution (surface speed 0.05-0.5 m/s, any direction),
    so the turns sway the DVL frame by up to the current either way. The steady manoeuvres
    are flown on survey lines and the turns end (``_as_flown``), so every mission turns,
    as every real survey segment does. In the navigator's place, the Snapir's waters
    (``SNAPIR_WATERS``)."""
    nav = navigator()
    missions = []
    for i, (name, kind, options) in enumerate(MANEUVER_MISSIONS):
        missions.append(MissionConfig(name=name, seed=200 + i, scenario=ScenarioConfig(
            name=kind, speed=2.0, depth=20.0, duration=duration,
            options=_as_flown(kind, 2.0, options))))
        speed, slow = SLOW_OPTIONS.get(kind, (SLOW_SPEED, {}))
        missions.append(MissionConfig(name=f"{name}_slow", seed=300 + i,
                                      scenario=ScenarioConfig(
                                          name=kind, speed=speed, depth=20.0,
                                          duration=duration,
                                          options=_as_flown(kind, speed,
                                                            {**options, **slow}))))
    return dataclasses.replace(nav, missions=tuple(missions))


# The Snapir AUV's DVL is mounted yawed 45 deg from the body: its recorded velocities
# (../shared/reference/beamsnet-reference.md) average (1.13, -1.17, 0) m/s in the DVL frame
# while the vehicle flies forward, i.e. the body's x axis is at -45 deg in the DVL frame.
SNAPIR_MOUNTING_YAW_DEG = 45.0


def sim2real(duration: float = 600.0, mounting_yaw_deg: float = SNAPIR_MOUNTING_YAW_DEG
             ) -> Config:
    """The training data of ``beamsnet reproduce sim2real``: ``realistic_maneuvers`` (both
    speeds, each mission in its own current, the navigator's terrain and IMU) flown with
    the DVL error model the BeamsNet paper put on the Snapir streams (paper-sim's DVL: 20
    deg beams, s = 0.7 %, b = 1e-4 m/s, sigma = 0.042^2 m/s, no failures), mounted yawed
    ``mounting_yaw_deg`` from the body (the Snapir's 45 deg by default), so that its
    DVL-frame velocities are what the Snapir's DVL frame sees. The place is
    ``realistic_maneuvers``'s, the Snapir's waters, where the real streams were recorded:
    the IMU (which the Snapir streams' models do not read) measures the Earth there, and
    the DVL's data are those of a flat world's (the place changes no DVL array)."""
    dvl = dataclasses.replace(_paper(PAPER_NOISE_CODE).dvl,
                              mounting_rpy_deg=(0.0, 0.0, float(mounting_yaw_deg)))
    return dataclasses.replace(realistic_maneuvers(duration), dvl=dvl)


def _force_coefficients(model: str) -> tuple[float, float, float]:
    """A vehicle's coefficients that turn a velocity fluctuation into force: its axial
    drag (surge), its hull and fin-pair lift (sway, heave), and those lifts' moments about
    the origin (pitch, yaw), from its model (``hydro.Hydro``)."""
    from auvsim.physics.vehicle import Vehicle  # MuJoCo only where a vehicle is swapped

    h = Vehicle(model).hydro
    return (h.axial_drag, h.hull_lift + h.fin_lift,
            h.hull_lift * abs(h.hull_lift_x) + h.fin_lift * abs(h.fin_x))


def with_vehicle(config: Config, model: str) -> Config:
    """``config`` flown by the vehicle ``model`` (``--vehicle``), with what it sized for its
    own vehicle made the new one's:

    * the IMU's and the DVL's sites, where set (the presets' are the Snapir's, 1.8 m aft on
      the A18-D's 5.5 m hull: behind a REMUS 100's tail), go back to the model's own;
    * the water's turbulent wrench, which ``NAVIGATOR_WATER`` derives through the A18-D's
      force model from a velocity fluctuation, is that fluctuation through the new
      vehicle's: each force scaled by the ratio of the two vehicles' coefficients
      (``_force_coefficients``: surge by the axial drag, sway and heave by the hull and
      fin lift) and each moment by that of the lifts' moments, roll with pitch and yaw
      (the fins' span, roll's arm, taken to scale with the hull as their lever does).
      The A18-D's wrench unscaled turned a 31 kg REMUS 100 upside down.

    The same model returns ``config`` unchanged.
    """
    old = config.vehicle
    if model == old.model:
        return config
    vehicle = dataclasses.replace(old, model=model, imu_position=None, dvl_position=None)
    water = config.water
    if any(water.turbulence_force_std) or any(water.turbulence_moment_std):
        (old_x, old_y, old_m), (x, y, m) = (_force_coefficients(old.model),
                                            _force_coefficients(model))
        force = (x / old_x, y / old_y, y / old_y)  # surge, sway, heave
        water = dataclasses.replace(
            water, turbulence_force_std=tuple(f * k for f, k in
                                              zip(water.turbulence_force_std, force,
                                                  strict=True)),
            turbulence_moment_std=tuple(t * m / old_m for t in water.turbulence_moment_std))
    return dataclasses.replace(config, vehicle=vehicle, water=water)


PRESETS = {
    "navigator": ("physical default: one mission over rough terrain in a coastal current "
                  "with turbulence; a Navigator-like 30 deg DVL with every failure and error "
                  "beyond eq. 7 (water track included); the navigation-full IMU, off Haifa "
                  "(the Earth's rate, WGS-84 gravity)", navigator),
    "paper-sim": ("the BeamsNet paper's simulation as its code ran it: 1, 2, 3 m/s x 7200 s, "
                  "20 deg beams, s = 0.7 %, b = 1e-4 m/s, sigma = 0.042^2 m/s",
                  lambda: _paper(PAPER_NOISE_CODE)),
    "paper-sim-text": ("the same with sigma = 0.042 m/s, as the paper's text states",
                       lambda: _paper(PAPER_NOISE_TEXT)),
    "maneuvers": ("every manoeuvre (turning circle, zigzags 10/10 and 20/20, lawnmower, depth "
                  "steps, yo-yo, speed steps, spiral dive, random waypoints) and a straight "
                  "line, 600 s each at 2 m/s, with the paper-sim sensors", maneuvers),
    "realistic-maneuvers": ("the same manoeuvres at 2 m/s and at 0.8 m/s, 600 s each, each "
                            "in its own current, with the navigator's terrain, disturbances "
                            "and every DVL and IMU effect, off Haifa", realistic_maneuvers),
    "sim2real": ("the realistic manoeuvres with the paper's DVL error model on the Snapir's "
                 "streams and its DVL mounting (yawed 45 deg): beamsnet reproduce sim2real "
                 "trains on it", sim2real),
}
DEFAULT_PRESET = "navigator"


def preset(name: str) -> Config:
    if name not in PRESETS:
        raise ConfigError(f"unknown preset {name!r}{did_you_mean(name, PRESETS)}: expected "
                          f"one of {', '.join(PRESETS)} "
                          "(auvsim presets lists them)")
    return PRESETS[name][1]()
