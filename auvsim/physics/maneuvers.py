"""Scripted manoeuvres: what the autopilots (or the actuators directly) are asked to do.

Each manoeuvre is a scenario (``auvsim generate --scenario NAME``) and, through
``ManeuverPolicy``, a policy for the gymnasium environment. A manoeuvre answers, for any
times ``t`` (s from the start), the reference of the three channels and whether each is
closed loop (``schedule``):

    channel      closed loop: reference       open loop: command
    0 speed      surge speed, m/s             shaft speed, rpm
    1 heading    heading, rad                 rudder angle, rad (+ turns to starboard)
    2 depth      depth, m                     stern-plane angle, rad

Every manoeuvre starts on its heading, at its depth and speed (the scenario's
``heading_deg``, ``depth``, ``speed``), and is parameterised by ``ScenarioConfig.options``
(names and defaults in each class's ``Options``). The Kempf zigzag switches its rudder when
the heading crosses a limit, so it is driven in short chunks with feedback (``run``); the
others are fixed schedules, computed for a whole block at once. ``phases`` names the parts
of a manoeuvre, for plots.

This module is a leaf: it knows the scenario only as an object with the attributes of
``Scenario`` (``auvsim.config.ScenarioConfig`` is one), and the registry ``MANEUVERS`` is
the one list of scenario names. Adding a manoeuvre is a subclass here, added to
``MANEUVERS``, and its tests.

The manoeuvres (Fossen 2021, ch. 13, describes the turning circle, the Kempf zigzag and the
spiral for ships; the depth and speed profiles are the usual AUV test legs):

    straight          constant speed, heading and depth
    turning_circle    lead-in, then a constant rudder angle, speed and depth held
    zigzag            Kempf zigzag: rudder +d until the heading has turned +psi, then -d
                      until it has turned -psi, ... (10/10: d = psi = 10 deg; 20/20)
    lawnmower         survey legs joined by cross legs, turns alternating port/starboard
    depth_steps       depth alternating between two levels
    yoyo              sawtooth depth profile (constant descent and ascent rates)
    speed_steps       speed alternating between two levels (accelerations, decelerations)
    spiral_dive       constant rudder while the depth reference descends at a steady rate
    random_waypoints  straight legs toward seeded random waypoints (planned, not guided)
"""

from __future__ import annotations

import dataclasses
import math
import reprlib
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar, NamedTuple, Protocol

import numpy as np

from auvsim.checks import did_you_mean, is_finite
from auvsim.errors import ConfigError

# A rudder beyond a fin's limit is held at the limit; beyond a right angle it means nothing.
MAX_RUDDER_DEG = 90.0
# Legs of a lawnmower or of random waypoints per mission: 72 h at 3 m/s over 300 m legs is
# about 2,600; more than this means legs of a few metres, planned in Python at every check.
MAX_LEGS = 100_000
MAX_WAYPOINTS = 1000


class Scenario(Protocol):
    """What a manoeuvre reads of its scenario (``auvsim.config.ScenarioConfig``)."""

    name: str
    speed: float  # m/s
    heading_deg: float  # deg from north
    depth: float  # m
    duration: float  # s
    start_speed: float | None  # m/s; None: start at ``speed``
    options: Mapping[str, float]


class Phase(NamedTuple):
    """A named part of a manoeuvre, from ``start`` to ``end`` (s)."""

    start: float
    end: float
    label: str


def _options(cls, config: Scenario):
    """The manoeuvre's ``Options`` dataclass from the config's ``options`` mapping, with
    unknown names and non-numbers refused."""
    known = {f.name: f.type for f in dataclasses.fields(cls)}
    given = dict(config.options)
    unknown = sorted(set(given) - set(known))
    if unknown:
        raise ConfigError(f"scenario.options: unknown option(s) {', '.join(unknown)} for "
                          f"{config.name}; expected some of {', '.join(sorted(known)) or 'none'}")
    for key, value in given.items():
        if not is_finite(value):
            raise ConfigError(f"scenario.options.{key}: expected a finite number, got "
                              f"{reprlib.repr(value)}")
    return cls(**given)


def _at_least(name: str, value: float, least: float, unit: str) -> None:
    if not value >= least:
        raise ConfigError(f"scenario.options.{name}: expected at least {least:g} {unit}, got "
                          f"{value!r}")


def _below_the_surface(name: str, depth: float, change: float) -> None:
    """A depth change from the scenario's ``depth`` must keep the depth reference positive
    (the scenario's own depth is checked so by its config)."""
    if not depth + change > 0:
        raise ConfigError(f"scenario.options.{name}: expected a change that keeps the depth "
                          f"below the surface (more than {-depth:g} m from {depth:g} m), got "
                          f"{change!r}")


def _positive(name: str, value: float) -> None:
    if not value > 0:
        raise ConfigError(f"scenario.options.{name}: expected a positive number, got {value!r}")


def _at_most(name: str, value: float, most: float, unit: str) -> None:
    if not value <= most:
        raise ConfigError(f"scenario.options.{name}: expected at most {most:g} {unit}, got "
                          f"{value!r}")


def _rudder(name: str, value: float) -> None:
    if not abs(value) <= MAX_RUDDER_DEG:
        raise ConfigError(f"scenario.options.{name}: expected a rudder angle in "
                          f"[-{MAX_RUDDER_DEG:g}, {MAX_RUDDER_DEG:g}] deg, got {value!r}")


def _too_many_legs(names: str, given: str) -> ConfigError:
    return ConfigError(f"scenario.options.{names}: expected legs long enough for at most "
                       f"{MAX_LEGS} in the mission, got {given}")


class Maneuver:
    """Base of the scripted manoeuvres; subclasses define ``Options`` and ``schedule``.

    Args:
        config: the scenario; ``config.options`` sets the manoeuvre's parameters.
        rng: the mission's seeded manoeuvre stream, required by manoeuvres that draw
            something (random waypoints).

    ``variants`` names the option sets the test library flies (``missions``): by default
    one mission named after the manoeuvre, with its default options.
    """

    name: ClassVar[str]
    variants: ClassVar[dict[str, dict[str, float]] | None] = None

    @dataclass(frozen=True)
    class Options:
        pass

    def __init__(self, config: Scenario, rng: np.random.Generator | None = None) -> None:
        self.config = config
        self.options = _options(self.Options, config)
        self.speed = config.speed
        self.heading = math.radians(config.heading_deg)
        self.depth = config.depth
        self.duration = config.duration
        if hasattr(self.options, "lead_s"):  # the straight lead-in of several manoeuvres
            _at_least("lead_s", self.options.lead_s, 0.0, "s")

    def initial_state(self) -> dict:
        start = self.speed if self.config.start_speed is None else self.config.start_speed
        return dict(position_ned=(0.0, 0.0, self.depth), yaw=self.heading,
                    velocity_body=(start, 0.0, 0.0))

    def speeds(self) -> tuple[float, ...]:
        """Every surge speed the manoeuvre asks the speed autopilot for, m/s."""
        return (self.speed,)

    def schedule(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3) references and (N, 3) bool closed-loop flags at times ``t`` (s)."""
        raise NotImplementedError

    def phases(self) -> list[Phase]:
        return [Phase(0.0, self.duration, self.name)]

    def reset(self) -> None:
        """Forget any feedback state (before a new run)."""

    def command(self, t: float, yaw: float) -> tuple[np.ndarray, np.ndarray]:
        """The (3,) reference and (3,) closed-loop flags at one time, given the heading
        (rad): what a policy asks for at each of its steps."""
        refs, closed = self.schedule(np.array([t]))
        return refs[0], closed[0]

    def run(self, vehicle, t: np.ndarray):
        """Drive ``vehicle`` over the physics steps at times ``t``; its ``Trajectory``."""
        refs, closed = self.schedule(t)
        return drive(vehicle, refs, closed)

    def _lead_then(self, label: str) -> list[Phase]:
        """Phases: straight for the ``lead_s`` option, then ``label`` to the end."""
        lead = min(self.options.lead_s, self.duration)
        return [Phase(0.0, lead, "straight"), Phase(lead, self.duration, label)]

    def _alternating(self, start: float, length: float, labels: tuple[str, str]) -> list[Phase]:
        """Phases of ``length`` s from ``start`` to the end, labelled in turn."""
        out, k = [], 0
        while start < self.duration:
            out.append(Phase(start, min(start + length, self.duration), labels[k % 2]))
            start, k = start + length, k + 1
        return out

    def _hold(self, n: int, speed=None, heading=None, depth=None) -> np.ndarray:
        """(n, 3) references: the given channels, the others at the scenario's values."""
        refs = np.empty((n, 3))
        refs[:, 0] = self.speed if speed is None else speed
        refs[:, 1] = self.heading if heading is None else heading
        refs[:, 2] = self.depth if depth is None else depth
        return refs


def drive(vehicle, refs: np.ndarray, closed: np.ndarray):
    """Run the vehicle over the rows of ``refs``, one compiled call per stretch of steps
    whose closed-loop flags stay the same; the concatenated ``Trajectory``."""
    change = np.flatnonzero((closed[1:] != closed[:-1]).any(axis=1)) + 1
    bounds = [0, *change.tolist(), len(refs)]
    return _joined([vehicle.run(refs[a:b], tuple(bool(c) for c in closed[a]))
                    for a, b in zip(bounds[:-1], bounds[1:], strict=True)])


def _joined(parts: list):
    """One ``Trajectory`` from consecutive ones."""
    if len(parts) == 1:
        return parts[0]
    return type(parts[0])(*(np.concatenate(fields) for fields in zip(*parts, strict=True)))


ALL_CLOSED = np.array([True, True, True])
RUDDER_OPEN = np.array([True, False, True])


def survey_legs(heading: float, speed: float, duration: float, leg_m: float,
                spacing_m: float) -> list[tuple[float, float, float, str]]:
    """(start s, end s, heading rad, label) of every leg of a survey pattern that starts
    within ``duration``: legs of ``leg_m`` alternating between ``heading`` and its reverse,
    joined by cross legs of ``spacing_m`` to starboard (so the turns alternate starboard
    and port), each timed at ``speed``."""
    legs, start, k = [], 0.0, 0
    while start < duration:
        if len(legs) == MAX_LEGS:
            raise _too_many_legs("leg_m, spacing_m", f"{leg_m!r} and {spacing_m!r} m over "
                                 f"{duration:g} s at {speed:g} m/s")
        along = k % 2 == 0
        length = leg_m if along else spacing_m
        leg_heading = heading + (math.pi * (k // 2 % 2) if along else math.pi / 2)
        end = start + length / speed
        legs.append((start, end, leg_heading, "survey leg" if along else "cross leg"))
        start, k = end, k + 1
    return legs


class _OnSurveyLines(Maneuver):
    """A manoeuvre flown along survey lines when its ``leg_m`` option is positive: its
    heading follows ``survey_legs`` (legs of ``leg_m``, cross legs of ``spacing_m``) as an
    AUV's survey flies parallel track lines joined by turns at their ends; 0 (the default)
    holds the scenario's heading. ``Options`` must have ``leg_m`` and ``spacing_m``."""

    def __init__(self, config, rng=None):
        super().__init__(config, rng)
        o = self.options
        if o.leg_m != 0.0:
            _at_least("leg_m", o.leg_m, 1.0, "m")
            _at_least("spacing_m", o.spacing_m, 1.0, "m")
            self.legs = survey_legs(self.heading, self.speed, self.duration, o.leg_m,
                                    o.spacing_m)

    def phases(self) -> list[Phase]:
        """Each survey leg and cross leg (its turns) where there are legs, else the one
        phase of the manoeuvre."""
        if self.options.leg_m == 0.0:
            return super().phases()
        return [Phase(a, min(b, self.duration), label) for a, b, _, label in self.legs]

    def headings(self, t: np.ndarray) -> np.ndarray | None:
        """(N,) heading references (rad) at times ``t``, or None for the scenario's."""
        if self.options.leg_m == 0.0:
            return None
        starts = np.array([leg[0] for leg in self.legs])
        i = np.searchsorted(starts, t, side="right") - 1
        return np.array([leg[2] for leg in self.legs])[i]


class Straight(_OnSurveyLines):
    """Constant speed, heading and depth (on survey lines with ``leg_m``)."""

    name = "straight"

    @dataclass(frozen=True)
    class Options:
        leg_m: float = 0.0  # 0: one heading
        spacing_m: float = 50.0

    def schedule(self, t):
        return self._hold(len(t), heading=self.headings(t)), np.tile(ALL_CLOSED, (len(t), 1))


class TurningCircle(Maneuver):
    """Straight for ``lead_s``, then the rudder held at ``rudder_deg`` (positive turns to
    starboard) with speed and depth held: the heading then advances monotonically. With
    ``turn_s`` positive the rudder is held that long only, and the heading autopilot then
    brings the vehicle back to its initial heading for the rest of the mission (a few
    circles, then a leg); 0 (the default) turns to the end."""

    name = "turning_circle"
    turn_label: ClassVar[str] = "turn"

    @dataclass(frozen=True)
    class Options:
        rudder_deg: float = 15.0  # a standard turn; the A18-D's full rudder is 41 deg
        lead_s: float = 20.0
        turn_s: float = 0.0  # 0: to the end

    def __init__(self, config, rng=None):
        super().__init__(config, rng)
        _rudder("rudder_deg", self.options.rudder_deg)
        _at_least("turn_s", self.options.turn_s, 0.0, "s")

    def schedule(self, t):
        o = self.options
        turning = t >= o.lead_s
        if o.turn_s > 0.0:
            turning &= t < o.lead_s + o.turn_s
        refs = self._hold(len(t))
        refs[turning, 1] = math.radians(o.rudder_deg)
        closed = np.where(turning[:, None], RUDDER_OPEN, ALL_CLOSED)
        return refs, closed

    def phases(self):
        o = self.options
        if o.turn_s <= 0.0 or o.lead_s + o.turn_s >= self.duration:
            return self._lead_then(self.turn_label)
        end = o.lead_s + o.turn_s
        return [*self._lead_then(self.turn_label)[:1], Phase(o.lead_s, end, self.turn_label),
                Phase(end, self.duration, "straight")]


class Zigzag(Maneuver):
    """Kempf zigzag: after ``lead_s`` straight, rudder +``rudder_deg`` until the heading
    has changed by +``angle_deg`` from the initial heading, then -``rudder_deg`` until it
    has changed by -``angle_deg``, and so on (the 20/20 zigzag by default; 10/10 with
    both at 10). Speed and depth are held. The rudder is decided every ``check_s``."""

    name = "zigzag"
    # The two zigzags of the manoeuvring standards (IMO MSC.137(76)); both rudders lie
    # within the A18-D's 41 deg rudder limit.
    variants = {"zigzag_10_10": {"angle_deg": 10.0, "rudder_deg": 10.0},
                "zigzag_20_20": {"angle_deg": 20.0, "rudder_deg": 20.0}}

    @dataclass(frozen=True)
    class Options:
        angle_deg: float = 20.0
        rudder_deg: float = 20.0  # beyond a fin's limit the servo stops at the limit
        lead_s: float = 20.0
        check_s: float = 0.1

    def __init__(self, config, rng=None):
        super().__init__(config, rng)
        for name in ("angle_deg", "rudder_deg", "check_s"):
            _positive(name, getattr(self.options, name))
        # The heading change is measured within a half turn either way.
        if not self.options.angle_deg < 180.0:
            raise ConfigError(f"scenario.options.angle_deg: expected a heading change below "
                              f"180 deg, got {self.options.angle_deg!r}")
        _rudder("rudder_deg", self.options.rudder_deg)
        self.reset()

    def reset(self):
        self.sign = 1.0  # the first swing goes to starboard

    def command(self, t, yaw):
        o = self.options
        if t < o.lead_s:
            return self._hold(1)[0], ALL_CLOSED
        turned = math.remainder(yaw - self.heading, 2 * math.pi)
        if self.sign * turned >= math.radians(o.angle_deg):
            self.sign = -self.sign
        ref = self._hold(1)[0]
        ref[1] = self.sign * math.radians(o.rudder_deg)
        return ref, RUDDER_OPEN

    def run(self, vehicle, t):
        chunk = max(1, round(self.options.check_s / vehicle.dt))
        parts = []
        for a in range(0, len(t), chunk):
            yaw = vehicle.yaw()
            ref, closed = self.command(float(t[a]), yaw)
            n = min(chunk, len(t) - a)
            parts.append(vehicle.run(np.tile(ref, (n, 1)), tuple(bool(c) for c in closed)))
        return _joined(parts)

    def phases(self):
        return self._lead_then("zigzag")


class Lawnmower(_OnSurveyLines):
    """Survey legs of ``leg_m`` alternating between the initial heading and its reverse,
    joined by cross legs of ``spacing_m`` to starboard; each leg is timed at the set
    speed, and the heading autopilot turns at full rudder between them. Unlike the
    manoeuvres flown on survey lines as an option, ``leg_m`` 0 is refused: a lawnmower
    has legs."""

    name = "lawnmower"

    @dataclass(frozen=True)
    class Options:
        leg_m: float = 300.0
        spacing_m: float = 50.0

    def __init__(self, config, rng=None):
        super().__init__(config, rng)
        _at_least("leg_m", self.options.leg_m, 1.0, "m")  # 0 passes _OnSurveyLines

    def schedule(self, t):
        return self._hold(len(t), heading=self.headings(t)), np.tile(ALL_CLOSED, (len(t), 1))


class _Steps(_OnSurveyLines):
    """One channel's reference alternating between the scenario's value and ``other()``
    every ``period_s`` (``Options`` must have ``period_s``, ``leg_m`` and ``spacing_m``)."""

    channel: ClassVar[int]  # 0 speed, 2 depth
    unit: ClassVar[str]

    def __init__(self, config, rng=None):
        super().__init__(config, rng)
        _at_least("period_s", self.options.period_s, 1.0, "s")

    def levels(self) -> tuple[float, float]:
        raise NotImplementedError

    def schedule(self, t):
        first, second = self.levels()
        refs = self._hold(len(t), heading=self.headings(t))
        refs[:, self.channel] = np.where((t // self.options.period_s) % 2 == 0, first, second)
        return refs, np.tile(ALL_CLOSED, (len(t), 1))

    def phases(self):
        first, second = self.levels()
        return self._alternating(0.0, self.options.period_s,
                                 (f"{first:g} {self.unit}", f"{second:g} {self.unit}"))


class DepthSteps(_Steps):
    """The depth reference alternates between ``depth`` and ``depth + step_m`` every
    ``period_s``, speed and heading held."""

    name = "depth_steps"
    channel, unit = 2, "m"

    @dataclass(frozen=True)
    class Options:
        step_m: float = 10.0
        period_s: float = 120.0
        leg_m: float = 0.0  # 0: one heading
        spacing_m: float = 50.0

    def __init__(self, config, rng=None):
        super().__init__(config, rng)
        _below_the_surface("step_m", self.depth, self.options.step_m)

    def levels(self):
        return self.depth, self.depth + self.options.step_m


class SpeedSteps(_Steps):
    """The speed reference alternates between ``speed`` and ``low`` every ``period_s``:
    a deceleration, then an acceleration, and so on; heading and depth held."""

    name = "speed_steps"
    channel, unit = 0, "m/s"

    @dataclass(frozen=True)
    class Options:
        low: float = 1.0
        period_s: float = 120.0
        leg_m: float = 0.0  # 0: one heading; legs timed at the higher speed
        spacing_m: float = 50.0

    def levels(self):
        return self.speed, self.options.low

    def speeds(self):
        return self.levels()


class Yoyo(_OnSurveyLines):
    """Sawtooth (triangle) depth profile between ``depth`` and ``depth + amplitude_m``,
    one descent and one ascent per ``period_s``, after ``lead_s`` level (on survey lines
    with ``leg_m``)."""

    name = "yoyo"

    @dataclass(frozen=True)
    class Options:
        amplitude_m: float = 10.0
        period_s: float = 200.0
        lead_s: float = 20.0
        leg_m: float = 0.0  # 0: one heading
        spacing_m: float = 50.0

    def __init__(self, config, rng=None):
        super().__init__(config, rng)
        _at_least("period_s", self.options.period_s, 1.0, "s")
        _below_the_surface("amplitude_m", self.depth, self.options.amplitude_m)

    def schedule(self, t):
        o = self.options
        phase = np.clip(t - o.lead_s, 0.0, None) % o.period_s / o.period_s  # 0..1
        triangle = 1.0 - np.abs(2.0 * phase - 1.0)  # 0 -> 1 -> 0
        depth = self.depth + o.amplitude_m * triangle
        return (self._hold(len(t), heading=self.headings(t), depth=depth),
                np.tile(ALL_CLOSED, (len(t), 1)))

    def phases(self):
        o = self.options
        return [Phase(0.0, min(o.lead_s, self.duration), "level"),
                *self._alternating(o.lead_s, o.period_s / 2, ("descent", "ascent"))]


class SpiralDive(TurningCircle):
    """A turning circle (after ``lead_s`` straight, the rudder held at ``rudder_deg``)
    while the depth reference descends at ``descent_rate`` m/s by ``dive_m`` in all."""

    name = "spiral_dive"
    turn_label = "spiral"

    @dataclass(frozen=True)
    class Options:
        rudder_deg: float = 10.0
        dive_m: float = 20.0
        descent_rate: float = 0.1
        lead_s: float = 20.0
        turn_s: float = 0.0  # 0: to the end

    def __init__(self, config, rng=None):
        super().__init__(config, rng)  # the rudder and lead_s, as a turning circle's
        _positive("descent_rate", self.options.descent_rate)
        _at_least("dive_m", self.options.dive_m, 0.0, "m")

    def schedule(self, t):
        o = self.options
        refs, closed = super().schedule(t)
        refs[:, 2] = self.depth + np.clip((t - o.lead_s) * o.descent_rate, 0.0, o.dive_m)
        return refs, closed


class RandomWaypoints(Maneuver):
    """Straight legs toward ``count`` waypoints drawn (seeded) within ``radius_m`` of the
    start and ``depth_span_m`` below the set depth; each leg is timed at the set speed
    from the previous waypoint (planned, not guided: the track passes near them). After
    the last waypoint the plan starts over from it."""

    name = "random_waypoints"

    @dataclass(frozen=True)
    class Options:
        count: float = 6
        radius_m: float = 300.0
        depth_span_m: float = 10.0

    def __init__(self, config, rng=None):
        super().__init__(config, rng)
        o = self.options
        _positive("radius_m", o.radius_m)
        _at_least("depth_span_m", o.depth_span_m, 0.0, "m")
        if o.count < 1 or o.count != int(o.count):
            raise ConfigError(f"scenario.options.count: expected a whole number >= 1, got "
                              f"{o.count!r}")
        _at_most("count", o.count, MAX_WAYPOINTS, "waypoints")
        if rng is None:
            raise ValueError("random_waypoints draws its waypoints: pass the mission's seeded "
                             "manoeuvre stream (rng=)")
        n = int(o.count)
        radius = o.radius_m * np.sqrt(rng.uniform(0.2, 1.0, n))
        bearing = rng.uniform(0.0, 2 * np.pi, n)
        points = np.c_[radius * np.cos(bearing), radius * np.sin(bearing),
                       self.depth + rng.uniform(0.0, o.depth_span_m, n)]
        start = np.array([0.0, 0.0, self.depth])
        legs, t = [], 0.0
        while t < self.duration:
            if len(legs) >= MAX_LEGS:
                raise _too_many_legs("radius_m", f"{o.radius_m!r} m over {self.duration:g} s "
                                     f"at {self.speed:g} m/s")
            for p in points:
                d = p[:2] - start[:2]
                length = max(float(np.hypot(*d)), 1.0)
                legs.append((t, math.atan2(d[1], d[0]), p[2]))
                t, start = t + length / self.speed, p
                if t >= self.duration:
                    break
        self.legs = np.array(legs)  # (start time, heading, depth) per leg
        self.waypoints = points

    def schedule(self, t):
        i = np.searchsorted(self.legs[:, 0], t, side="right") - 1
        refs = self._hold(len(t), heading=self.legs[i, 1], depth=self.legs[i, 2])
        return refs, np.tile(ALL_CLOSED, (len(t), 1))

    def phases(self):
        ends = [*self.legs[1:, 0], self.duration]
        return [Phase(float(a), float(min(b, self.duration)), f"leg {k + 1}")
                for k, (a, b) in enumerate(zip(self.legs[:, 0], ends, strict=True))]


MANEUVERS: dict[str, type[Maneuver]] = {
    m.name: m for m in (Straight, TurningCircle, Zigzag, Lawnmower, DepthSteps, Yoyo,
                        SpeedSteps, SpiralDive, RandomWaypoints)}


def make_maneuver(config: Scenario, rng: np.random.Generator | None = None) -> Maneuver:
    """The manoeuvre a scenario names, with its options checked.

    Args:
        config: the scenario.
        rng: the mission's manoeuvre stream (``auvsim.data.streams.mission_streams``); required
            by the manoeuvres that draw something.
    """
    if config.name not in MANEUVERS:
        raise ConfigError(f"scenario: expected one of {', '.join(MANEUVERS)}, got "
                          f"{config.name!r}{did_you_mean(config.name, MANEUVERS)}")
    return MANEUVERS[config.name](config, rng)


def check_scenario(config: Scenario) -> Maneuver:
    """Build the manoeuvre once to check its options, with a throwaway stream (what it
    draws is not used)."""
    return make_maneuver(config, rng=np.random.default_rng(0))


def missions() -> list[tuple[str, str, dict[str, float]]]:
    """The test library: (mission name, manoeuvre name, options) for every manoeuvre of
    ``MANEUVERS`` and each of its ``variants``, in registry order."""
    return [(mission, name, dict(options))
            for name, cls in MANEUVERS.items()
            for mission, options in (cls.variants or {name: {}}).items()]
