"""A mission played as a Water Linked DVL A50 plays on its network: newline-delimited JSON
over TCP (``auvsim serve DATASET --dvl a50``), so that a driver written for the instrument
reads simulated data unchanged.

The protocol is Water Linked's "DVL A50/A125 TCP JSON API" (docs.waterlinked.com, page
"dvl/dvl-json-protocol", source github.com/waterlinked/docs, docs/dvl/dvl-json-protocol.md;
the earlier page "dvl/dvl-protocol", section "JSON protocol (TCP)", gives the same
``json_v3.1``): a TCP server on port 16171, one JSON object per
line, sent to every connected client. auvsim sends, per ping of the mission:

- a *velocity-and-transducer report* (section "Velocity-and-transducer report"):
  ``{"time", "vx", "vy", "vz", "fom", "covariance", "altitude", "transducers",
  "velocity_valid", "status", "format": "json_v3.1", "type": "velocity",
  "time_of_validity", "time_of_transmission"}``;
- a *dead reckoning report* (section "Dead reckoning report"): ``{"ts", "x", "y", "z",
  "std", "roll", "pitch", "yaw", "type": "position_local", "status", "format"}``.

It answers the commands of the sections "Reset dead reckoning", "Calibrate gyro",
"Trigger ping" and "Configuration over TCP JSON API" (``get_config``, ``set_config``)
with ``{"response_to", "success", "error_message", "result", "format", "type":
"response"}``. ``trigger_ping`` is refused (``success: false``): auvsim plays the
mission's pings on their own clock and cannot ping on demand. The TCP JSON API has no
command that gives the protocol version (the serial protocol's ``wcv`` does); reports
carry it in ``format``, and any command the API does not define is answered with
``success: false`` and an error message naming it.

Where each field comes from (a simulated mission; ``velocity_report`` builds the report
of one ping, ``mission_pings`` reads the arrays):

- ``vx vy vz``: ``dvl/velocity_ls``, the least-squares velocity of the measured beams,
  in the DVL frame: the A50's own frame with a ``mounting_rotation_offset`` of 0, which
  is what ``get_config`` reports (the protocol's frame is the DVL's "body frame", x
  forward, y right, z down, page "dvl/axes": auvsim's DVL frame is that).
- ``velocity_valid``: the ping is in bottom track (``dvl/mode`` 0). A water-track ping
  is sent as not valid: ``json_v3.1`` cannot say that a velocity is relative to the
  water (``json_v3.2`` adds ``tracking_mode`` for that). When not valid, ``vx vy vz``
  are 0, and ``altitude`` is -1 when no beam has bottom lock: the values the serial
  protocol's section "Velocity report, old format (wrx)" shows for no lock.
- ``covariance``: the covariance of the error that the mission's noise model puts into
  ``velocity_ls``: the white beam noise through the least squares,
  ``P diag(sigma_k^2) P^T`` with ``P`` the pseudo-inverse of the rows of H of the beams
  used and ``sigma_k = noise_std + noise_range_coeff r_k + noise_speed_coeff |v|``
  (``auvsim.interop.pings.ping_errors``, shared with the ROS 2 export; the dataset's
  config), plus the shared
  Gauss-Markov velocity error's stationary variance ``dvl_slow_error_std^2 I``. Scale
  factors, biases, misalignment (systematic) and outliers (heavy-tailed) are not in it.
  -1 in every entry when the ping has no velocity (``velocity_valid`` false), as
  ``marine_acoustic_msgs/Dvl`` marks an unknown covariance.
- ``fom``: the square root of the covariance's largest eigenvalue, m/s. The document
  says only that the figure of merit "is calculated from" the covariance; this rule
  reproduces its example's fom (1.60163851e-4 m/s from the covariance shown) to 9
  significant digits
  (``tests/test_serve.py`` checks it), where the largest diagonal entry gives 1.564e-4.
  -1 when the covariance is.
- ``altitude``: "distance to the reflecting surface along the Z axis": the mean over
  the bottom-locked beams (``ping_errors``) of ``r_k cos(alpha)`` (the slant range's
  component on the DVL's z axis; ``cos(alpha)`` is H's z column), -1 when no beam has
  bottom lock.
- ``transducers[k]``: ``id`` k - 1 for auvsim's beam k (column k - 1 of the dataset's
  beam arrays); ``velocity`` ``dvl/beam_velocity``, ``distance`` ``dvl/beam_range``
  (along the beam), ``beam_valid`` the beam measured with bottom lock (``dvl/valid``,
  a finite velocity and ``dvl/status`` ok or outlier). A beam without it has
  ``velocity`` 0 and ``distance`` -1 (section "Transducer report (wru)": "If the
  transducer did not receive a signal which could be successfully decoded, distance
  will be set to -1, and velocity will be set to 0"). ``rssi`` and ``nsd`` (dBm) are
  not simulated: auvsim has no acoustic link budget. The document says they are "outputted in all
  cases", and drivers read them as numbers, so they are constants: ``RSSI_DBM`` (-50)
  for a beam with an echo and ``NSD_DBM`` (-95) for every beam's noise, inside the
  ranges of the document's examples (-27 to -62 dBm, -88 to -104 dBm), so a driver
  that gates beams on ``rssi - nsd`` keeps the valid ones; a beam without an echo has
  ``rssi`` at the noise, -95. They carry no information.
- ``status``: 0. Its only defined bit is a high-temperature warning; auvsim has no
  temperature.
- ``time``: milliseconds since the previous ping on the mission clock (the first
  ping: the ping interval, ``1000 / dvl_rate_hz``).
- ``time_of_validity``: the ping's time on the mission clock, as a Unix time in
  microseconds: the wall-clock time at which the server started plus the ping's time
  from the first ping (at ``speed`` 1 it is the wall-clock time of the ping; faster,
  the stamps keep the mission's spacing). ``time_of_transmission``: the wall-clock
  time, Unix microseconds, read just before the report is written to the sockets.
  (A real A50's transmission comes 100-200 ms after its validity: the echo's travel
  and its processing; auvsim sends at the ping's time.)

Beam geometry, mapped honestly: auvsim's beam k points at azimuth
``psi_k = (k - 1) 90 deg + 45 deg`` from the DVL's x axis at the mission's beam angle
(``auvsim.data.beams``; 30 deg in the presets). Water Linked documents the A50's
transducer positions only as a figure (page "dvl/dvl-a50-details", "Transducer
numbering") and its transducer ids as the figure's numbers minus one (page "dvl/axes",
"Transducer numbering and protocol IDs"); auvsim does not claim that its beam k sits
where the A50's transducer k does, nor that its beam angle is the A50's. The velocity in
the report is auvsim's least squares over its own geometry; a driver that solves the
four transducer velocities with the A50's geometry gets another velocity.

Dead reckoning (the A50 integrates its velocities with its own IMU's attitude, page
"dvl/dead-reckoning"): auvsim integrates the reported velocity, held from the last valid
ping, rotated by the attitude of the DVL at each ping (the truth's quaternion and the
DVL's true mounting: nominal times the realised misalignment), by the rectangle rule over
the ping intervals, in the frame of the DVL at the last reset (or the first ping), as
the page defines it; ``roll pitch yaw`` (deg, ZYX) are the DVL's attitude relative to
that frame, so zero at a reset. ``std`` is ``sqrt(sum (fom dt)^2)`` over the intervals
since the reset (pings' errors taken as independent, which the Gauss-Markov error is
not: it is a lower figure). ``status`` is 1 while the held velocity is not the ping's
own. One report per ping (the A50 sends about 5 Hz). ``ts`` is the ping's
``time_of_validity`` in seconds.

Only simulated missions are served: an imported or recorded mission has no truth
attitude and may have no beams.
"""

from __future__ import annotations

import errno
import json
import math
import random
import selectors
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from auvsim.errors import ConfigError, DatasetError

PORT = 16171  # "The DVL runs a TCP server on port 16171"
FORMAT = "json_v3.1"
RSSI_DBM = -50.0  # not simulated: see the module docstring
NSD_DBM = -95.0
# get_config's values at the start; set_config checks a value against its default's type.
SETTINGS = {"speed_of_sound": 1500.0, "mounting_rotation_offset": 0.0,
            "acoustic_enabled": True, "dark_mode_enabled": False, "range_mode": "auto",
            "periodic_cycling_enabled": True}
_MAX_LINE = 1 << 16  # a command longer than this without a newline: the client is dropped
_MAX_PENDING = 1 << 22  # bytes queued for a client that does not read: it is dropped


@dataclass(frozen=True)
class Pings:
    """A mission's DVL pings, as the A50 reports them (arrays over M pings).

    Attributes:
        name: the mission.
        time: (M,) ping times, s, mission clock.
        interval_ms: (M,) ms since the previous ping (the first: the ping interval).
        velocity: (M, 3) ``dvl/velocity_ls``, DVL frame, m/s (NaN: none).
        velocity_valid: (M,) bool, bottom track with a velocity.
        beam_velocity, beam_range: (M, 4) m/s, m (NaN: none).
        beam_valid: (M, 4) bool, the beam measured with bottom lock.
        altitude: (M,) m along the DVL's z axis, -1 without a bottom-locked beam.
        covariance: (M, 3, 3) (m/s)^2 (NaN: unknown).
        dvl_to_ned: (M, 3, 3) the DVL's true attitude at each ping (DVL frame -> NED).
    """

    name: str
    time: np.ndarray
    interval_ms: np.ndarray
    velocity: np.ndarray
    velocity_valid: np.ndarray
    beam_velocity: np.ndarray
    beam_range: np.ndarray
    beam_valid: np.ndarray
    altitude: np.ndarray
    covariance: np.ndarray
    dvl_to_ned: np.ndarray

    def __len__(self) -> int:
        return len(self.time)


def mission_pings(mission) -> Pings:
    """The pings of a simulated mission of an open dataset (``auvsim.data.reader.Mission``).

    Raises:
        DatasetError: the mission is not simulated, or has no pings.
    """
    from auvsim.interop.pings import ping_errors
    from auvsim.physics.frames import rotation_matrices, rotation_rpy
    from auvsim.sensors.dvl import Mode

    if mission.origin != "simulated" or not mission.has("truth"):
        raise DatasetError(f"mission {mission.name!r} is {mission.origin}; expected a "
                           "simulated mission (auvsim generate): an A50's reports need "
                           "its beams and the truth's attitude")
    a, dvl = mission.attrs, mission.dvl
    t = np.asarray(dvl.time, dtype=float)
    if len(t) == 0:
        raise DatasetError(f"mission {mission.name!r} has no DVL pings")
    beams, ranges = np.asarray(dvl.beam_velocity), np.asarray(dvl.beam_range)
    errors = ping_errors(mission)
    locked = errors.locked
    velocity = np.asarray(dvl.velocity_ls, dtype=float)
    # json_v3.1 has no word for water track: only a bottom-track velocity is valid
    valid = np.isfinite(errors.covariance[:, 0, 0]) & (locked.sum(axis=1) >= 3)
    if "mode" in dvl:
        valid &= np.asarray(dvl.mode) == int(Mode.BOTTOM_TRACK)
    altitude = np.where(np.isfinite(errors.altitude), errors.altitude, -1.0)
    covariance = np.where(valid[:, None, None], errors.covariance, np.nan)

    mounting = rotation_rpy(*np.radians(a["dvl_mounting_rpy_deg"]))
    if "dvl_misalignment_rpy_deg" in a:  # true DVL frame -> nominal
        mounting = mounting @ rotation_rpy(*np.radians(a["dvl_misalignment_rpy_deg"]))
    rows = np.asarray(mission.imu.index_of_dvl)
    dvl_to_ned = rotation_matrices(np.asarray(mission.truth.quaternion)[rows]) @ mounting
    interval = np.diff(t, prepend=t[0] - 1.0 / float(a["dvl_rate_hz"])) * 1e3
    return Pings(mission.name, t, interval, velocity, valid, beams, ranges, locked, altitude,
                 covariance, dvl_to_ned)


def figure_of_merit(covariance: np.ndarray) -> float:
    """The A50's figure of merit of a (3, 3) velocity covariance, (m/s)^2 -> m/s: the
    square root of its largest eigenvalue (the module docstring says why)."""
    return float(math.sqrt(max(np.linalg.eigvalsh(covariance)[-1], 0.0)))


def velocity_report(pings: Pings, n: int, *, time_of_validity: int,
                    time_of_transmission: int) -> dict:
    """The velocity-and-transducer report of ping ``n`` (the module docstring gives each
    field's source).

    Args:
        pings: the mission's pings.
        n: the ping, 0 to M - 1.
        time_of_validity, time_of_transmission: Unix times, microseconds.
    """
    ok = bool(pings.velocity_valid[n])
    v = pings.velocity[n] if ok else np.zeros(3)
    cov = pings.covariance[n] if ok else np.full((3, 3), -1.0)
    transducers = []
    for k in range(4):
        beam = bool(pings.beam_valid[n, k])
        transducers.append({
            "id": k,
            "velocity": float(pings.beam_velocity[n, k]) if beam else 0.0,
            "distance": float(pings.beam_range[n, k]) if beam else -1.0,
            "rssi": RSSI_DBM if beam else NSD_DBM,
            "nsd": NSD_DBM,
            "beam_valid": beam})
    return {"time": float(pings.interval_ms[n]),
            "vx": float(v[0]), "vy": float(v[1]), "vz": float(v[2]),
            "fom": figure_of_merit(cov) if ok else -1.0,
            "covariance": cov.tolist(),
            "altitude": float(pings.altitude[n]),
            "transducers": transducers,
            "velocity_valid": ok,
            "status": 0,
            "format": FORMAT,
            "type": "velocity",
            "time_of_validity": int(time_of_validity),
            "time_of_transmission": int(time_of_transmission)}


def rpy_deg(rotation: np.ndarray) -> tuple[float, float, float]:
    """Roll, pitch, yaw, deg (ZYX), of a (3, 3) rotation (``frames.rotation_rpy``'s
    inverse)."""
    return (math.degrees(math.atan2(rotation[2, 1], rotation[2, 2])),
            math.degrees(-math.asin(max(-1.0, min(1.0, rotation[2, 0])))),
            math.degrees(math.atan2(rotation[1, 0], rotation[0, 0])))


@dataclass
class DeadReckoning:
    """The A50's dead reckoning over auvsim's pings (the module docstring gives the
    model): call ``step`` at every ping in order; ``reset`` starts a new run at the next."""

    origin: np.ndarray | None = None  # (3, 3) DVL frame at the reset -> NED
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    variance: float = 0.0
    held: np.ndarray = field(default_factory=lambda: np.zeros(3))  # DVL frame, m/s
    held_fom: float = 0.0
    previous: tuple[np.ndarray, float] | None = None  # (DR-frame velocity, fom) held

    def reset(self) -> None:
        self.origin = None

    def step(self, pings: Pings, n: int, ts: float) -> dict:
        """The dead reckoning report at ping ``n``, ``ts`` its Unix time, s."""
        rotation = pings.dvl_to_ned[n]
        if self.origin is None:
            self.origin, self.position, self.variance = rotation, np.zeros(3), 0.0
        elif self.previous is not None:
            dt = pings.interval_ms[n] / 1e3
            self.position = self.position + self.previous[0] * dt
            self.variance += (self.previous[1] * dt) ** 2
        own = bool(pings.velocity_valid[n])
        if own:
            self.held = pings.velocity[n]
            self.held_fom = figure_of_merit(pings.covariance[n])
        relative = self.origin.T @ rotation
        self.previous = (relative @ self.held, self.held_fom)
        roll, pitch, yaw = rpy_deg(relative)
        x, y, z = (float(c) for c in self.position)
        return {"ts": ts, "x": x, "y": y, "z": z, "std": math.sqrt(self.variance),
                "roll": roll, "pitch": pitch, "yaw": yaw, "type": "position_local",
                "status": 0 if own else 1, "format": FORMAT}


def respond(line: bytes, settings: dict, dead_reckoning: DeadReckoning) -> dict:
    """The response to one command line of a client (``settings`` and ``dead_reckoning``
    are the server's, changed by ``set_config`` and ``reset_dead_reckoning``)."""
    def answer(command, error: str = "", result=None) -> dict:
        return {"response_to": command, "success": not error, "error_message": error,
                "result": result, "format": FORMAT, "type": "response"}

    try:
        message = json.loads(line)
    except (ValueError, RecursionError):
        return answer(None, "not a JSON object; expected {\"command\": NAME, ...} on one line")
    if not isinstance(message, dict) or not isinstance(message.get("command"), str):
        return answer(None, "no \"command\"; expected {\"command\": NAME, ...}")
    command = message["command"]
    if command == "get_config":
        return answer(command, result=dict(settings))
    if command == "set_config":
        parameters = message.get("parameters")
        if not isinstance(parameters, dict) or not parameters:
            return answer(command, "expected \"parameters\": an object of settings to set")
        problem = next(filter(None, (_setting_problem(k, v) for k, v in parameters.items())),
                       "")
        if problem:
            return answer(command, problem)
        settings.update({k: float(v) if isinstance(SETTINGS[k], float) else v
                         for k, v in parameters.items()})
        return answer(command)
    if command == "reset_dead_reckoning":
        dead_reckoning.reset()
        return answer(command)
    if command == "calibrate_gyro":  # the attitude is the mission's: nothing to calibrate
        return answer(command)
    if command == "trigger_ping":
        return answer(command, "auvsim plays the mission's pings on their own clock; it "
                      "cannot ping on demand")
    return answer(command, f"unknown command {command[:80]!r}; expected get_config, "
                  "set_config, reset_dead_reckoning, calibrate_gyro or trigger_ping")


def _setting_problem(name: str, value) -> str:
    """What is wrong with one ``set_config`` parameter, or ""."""
    if name not in SETTINGS:
        return f"unknown parameter {name[:80]!r}; expected one of {', '.join(SETTINGS)}"
    default = SETTINGS[name]
    if isinstance(default, bool):
        return "" if isinstance(value, bool) else f"{name}: expected true or false"
    if isinstance(default, float):
        low, high = (1000, 2000) if name == "speed_of_sound" else (0, 360)
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not low <= value <= high:
            return f"{name}: expected a number in [{low}, {high}], got {value!r:.80}"
        return ""
    return "" if isinstance(value, str) else f"{name}: expected a string"


class Lateness:
    """Running statistics of the reports' lateness, s, in constant memory (a server that
    loops runs for days): the count, the largest, the count over 5 ms (the target), and
    a uniform sample of at most ``RESERVOIR`` values (reservoir sampling, Vitter's
    algorithm R, seeded: the same lateness gives the same sample) for the median, exact
    while fewer values came."""

    RESERVOIR = 4096
    LIMIT_S = 0.005

    def __init__(self) -> None:
        self.count, self.largest, self.over = 0, 0.0, 0
        self.sample: list[float] = []
        self._rng = random.Random(0)

    def add(self, seconds: float) -> None:
        self.count += 1
        self.largest = max(self.largest, seconds)
        self.over += seconds > self.LIMIT_S
        if len(self.sample) < self.RESERVOIR:
            self.sample.append(seconds)
        else:
            k = self._rng.randrange(self.count)
            if k < self.RESERVOIR:
                self.sample[k] = seconds

    def median(self) -> float:
        """The sample's median, s (NaN before any report)."""
        return float(np.median(self.sample)) if self.sample else math.nan


class _Client:
    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        self.inbox = b""
        self.outbox = bytearray()


def serve(dataset: str | Path, mission: str | None = None, *, host: str = "127.0.0.1",
          port: int = PORT, speed: float = 1.0, loop: bool = False,
          wait_for_client: bool = False, ready: Callable[[str, int, Pings], None] | None = None,
          stop: threading.Event | None = None) -> dict:
    """Play a simulated mission's DVL as a Water Linked A50 on TCP until its last ping
    (every lap of it with ``loop``), ``stop`` is set, or Ctrl-C; then close every
    socket. One thread: a selector waits for clients and commands until the next ping
    is due, scheduled against ``time.monotonic()`` from the start (no drift).

    Args:
        dataset: an auvsim dataset.
        mission: its name; None for a dataset of one mission.
        host, port: where to listen (port 0: any free port, ``ready`` says which).
        speed: the mission's seconds per wall-clock second, > 0.
        loop: play the mission again from its start after its last ping, until stopped.
        wait_for_client: start the mission's clock when the first client connects, so
            that it reads every ping (a real A50 pings whether anyone listens or not).
        ready: called with (host, port, pings) once listening.
        stop: set it (from another thread) to stop within 50 ms.

    Returns:
        ``{"mission", "reports", "clients", "lateness"}``: the velocity reports sent,
        the clients that connected, and the reports' lateness (``Lateness``: the
        monotonic clock once a ping's lines are written to every client's socket, minus
        when the ping was due), in constant memory however long ``loop`` plays.

    Raises:
        ConfigError: a speed, port or host that cannot be used, or a port in use.
        DatasetError: the dataset cannot be read, or the mission is not in it or not
            simulated.
    """
    from auvsim.data.reader import open_dataset

    if isinstance(speed, bool) or not isinstance(speed, (int, float)) \
            or not math.isfinite(speed) or speed <= 0:
        raise ConfigError(f"expected a factor > 0, got {speed!r}", argument="speed")
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise ConfigError(f"expected a TCP port in [0, 65535], got {port!r}", argument="port")
    with open_dataset(dataset) as ds:
        pings = mission_pings(ds.mission(mission))
    listener = _listen(host, port)
    selector = selectors.DefaultSelector()
    clients: dict[socket.socket, _Client] = {}
    try:
        selector.register(listener, selectors.EVENT_READ)
        if ready is not None:
            ready(host, listener.getsockname()[1], pings)
        accepted, settings, dead_reckoning = 0, dict(SETTINGS), DeadReckoning()
        while wait_for_client and not clients and (stop is None or not stop.is_set()):
            accepted += _handle(selector, listener, clients, settings, dead_reckoning,
                                timeout=0.05)
        summary = _play(pings, listener, selector, clients, settings, dead_reckoning,
                        speed=speed, loop=loop, stop=stop)
        return {**summary, "clients": summary["clients"] + accepted}
    finally:
        for client in list(clients.values()):
            client.sock.close()
        selector.close()
        listener.close()


def _listen(host: str, port: int) -> socket.socket:
    """A listening socket, or a ConfigError naming the host or port that cannot be used."""
    try:
        return socket.create_server((host, port))  # SO_REUSEADDR: a closed port rebinds
    except OSError as e:
        # A name that does not resolve: gaierror from getaddrinfo, or, from bind, an
        # OSError with getaddrinfo's (negative) EAI code.
        if isinstance(e, socket.gaierror) or (e.errno is not None and e.errno < 0):
            raise ConfigError(f"{host[:80]!r}: not a host name or address here "
                              f"({e.strerror}); expected one such as 127.0.0.1",
                              argument="host") from None
        if e.errno == errno.EADDRINUSE:
            raise ConfigError(f"{port} is in use on {host}; expected a free port (another "
                              "server, or an A50 driver's simulator, holds it)",
                              argument="port") from None
        raise ConfigError(f"{port} on {host}: cannot listen ({e.strerror}); expected a port "
                          "and address this user may bind", argument="port") from None


def _play(pings: Pings, listener: socket.socket, selector: selectors.BaseSelector,
          clients: dict, settings: dict, dead_reckoning: DeadReckoning,
          *, speed: float, loop: bool, stop: threading.Event | None) -> dict:
    t = pings.time
    period = t[-1] - t[0] + pings.interval_ms[0] / 1e3  # one lap, and the gap to the next
    start, start_us = time.monotonic(), time.time_ns() // 1000
    lateness = Lateness()
    accepted, n, lap = 0, 0, 0
    while stop is None or not stop.is_set():
        offset = lap * period + (t[n] - t[0])  # mission seconds from the start
        due = start + offset / speed
        wait = due - time.monotonic()
        if wait > 0.003:  # the selector's timeout is rounded up to ms: wake >= 1 ms early
            accepted += _handle(selector, listener, clients, settings, dead_reckoning,
                                timeout=min(wait - 0.002, 0.05))
            continue
        # Commands and slow clients are served between pings even when pings come
        # faster than the selector's resolution.
        accepted += _handle(selector, listener, clients, settings, dead_reckoning, timeout=0)
        wait = due - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        validity = start_us + round(offset * 1e6)
        position = dead_reckoning.step(pings, n, validity / 1e6)
        report = velocity_report(pings, n, time_of_validity=validity,
                                 time_of_transmission=time.time_ns() // 1000)
        line = (json.dumps(report) + "\n" + json.dumps(position) + "\n").encode()
        for client in list(clients.values()):
            _send(selector, clients, client, line)
        lateness.add(time.monotonic() - due)  # once written to every client's socket
        n += 1
        if n == len(pings):
            if not loop:
                break
            n, lap = 0, lap + 1
    _flush(selector, listener, clients, settings, dead_reckoning, seconds=1.0)
    return {"mission": pings.name, "reports": lateness.count, "clients": accepted,
            "lateness": lateness}


def _handle(selector, listener, clients, settings, dead_reckoning, *, timeout: float) -> int:
    """Accept clients, answer their commands and write what is queued, for up to
    ``timeout`` s; returns the clients accepted."""
    accepted = 0
    for key, events in selector.select(timeout):
        sock = key.fileobj
        if sock is listener:
            try:
                conn, _ = listener.accept()
            except (BlockingIOError, ConnectionAbortedError):
                continue
            conn.setblocking(False)
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            clients[conn] = _Client(conn)
            selector.register(conn, selectors.EVENT_READ)
            accepted += 1
            continue
        client = clients.get(sock)
        if client is None:
            continue
        if events & selectors.EVENT_WRITE:
            _send(selector, clients, client, b"")
        if events & selectors.EVENT_READ and sock in clients:
            try:
                data = sock.recv(65536)
            except (BlockingIOError, InterruptedError):
                continue
            except OSError:
                data = b""
            if not data:
                _drop(selector, clients, client)
                continue
            client.inbox += data
            *lines, client.inbox = client.inbox.split(b"\n")
            if len(client.inbox) > _MAX_LINE:
                _drop(selector, clients, client)
                continue
            for line in lines:
                if line.strip():
                    reply = respond(line, settings, dead_reckoning)
                    _send(selector, clients, client, (json.dumps(reply) + "\n").encode())
    return accepted


def _send(selector, clients, client: _Client, data: bytes) -> None:
    """Queue ``data`` for a client and write what the socket takes now; a client that
    has gone, or lets more than ``_MAX_PENDING`` bytes pile up, is dropped."""
    if client.sock not in clients:
        return
    client.outbox += data
    try:
        sent = client.sock.send(client.outbox) if client.outbox else 0
    except (BlockingIOError, InterruptedError):
        sent = 0
    except OSError:
        _drop(selector, clients, client)
        return
    del client.outbox[:sent]
    if len(client.outbox) > _MAX_PENDING:
        _drop(selector, clients, client)
        return
    events = selectors.EVENT_READ | (selectors.EVENT_WRITE if client.outbox else 0)
    if selector.get_key(client.sock).events != events:
        selector.modify(client.sock, events)


def _drop(selector, clients, client: _Client) -> None:
    clients.pop(client.sock, None)
    selector.unregister(client.sock)
    client.sock.close()


def _flush(selector, listener, clients, settings, dead_reckoning, *, seconds: float) -> None:
    """At the end, give the clients up to ``seconds`` to take what is queued for them."""
    deadline = time.monotonic() + seconds
    while any(c.outbox for c in clients.values()) and time.monotonic() < deadline:
        _handle(selector, listener, clients, settings, dead_reckoning, timeout=0.01)
