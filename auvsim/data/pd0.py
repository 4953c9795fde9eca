"""Teledyne RDI PD0, both ways: ``auvsim export --to pd0`` writes a mission's DVL pings as a
Workhorse Navigator's bottom-track ensembles; ``auvsim import --format pd0`` reads a
Workhorse DVL's PD0 file into a recorded mission's ``dvl/`` group.

The layout is Teledyne RD Instruments, "WorkHorse Commands and Output Data Format"
(P/N 957-6156-00, February 2013), chapter "PD0 Output Format": Figure "PD0 Standard Output
Data Buffer Format" (header, fixed leader, variable leader, the data types, two reserved
bytes, the checksum), Table "Header Data Format" (7F7Fh, the ensemble's length without
the checksum, the number of data types and their offsets), Table "Fixed Leader Data
Format" (system configuration: frequency, convex head, up/down, beam angle, Janus
layout; the coordinate transformation byte of the EX command, bits 3-4: 00 beam, 01
instrument), Table "Variable Leader Data Format" (ensemble number, the real-time clock
with its Y2K century bytes) and Table "Bottom-Track Data Format" (0600h: range per beam,
cm, its MSB byte at 78-81; velocity per beam, mm/s, -32768 bad; percent good). The
checksum is the sum of the ensemble's bytes modulo 65536 (section "Example Program").
All values are little-endian. A Navigator is mounted with beam 3 45 deg to starboard of
forward, the heading alignment EA = 45 deg (Teledyne RDI, "WorkHorse Navigator Doppler
Velocity Log Technical Manual", installation chapter); beam and instrument axes and the
beam-to-instrument matrix are Teledyne RDI, "ADCP Coordinate Transformation: Formulas and
Calculations" (P/N 951-6079-00, 2010), sections 4 and 5.3 (instrument X from beam 1 to
beam 2, Y from beam 4 to beam 3, Z toward the face; a beam velocity is positive toward
the transducer).

auvsim's DVL frame (``auvsim.data.beams.beam_matrix``: x forward, z down, beams k = 0..3
at azimuths 45 + 90 k deg) is the Navigator's mounted so: RDI beam 3 is auvsim's beam 0
(forward-starboard), beam 2 its beam 1, beam 4 its beam 2, beam 1 its beam 3. The
velocity of the DVL over ground along a beam's outward direction (auvsim's beam
velocity) is the bottom's velocity toward the transducer (RDI's), so beam velocities keep
their sign. In instrument coordinates the bottom-track velocity is the bottom's relative
to the instrument, X, Y, Z, error: ``-R v`` with ``R`` auvsim's DVL frame -> RDI's
(``RDI_FROM_DVL``), and RDI's error velocity is minus auvsim's (whose beam pairs are
numbered the other way: ``auvsim.data.beams.error_velocity``).

What is written: the simulated-data flag set for a simulated mission (not for a recorded
one); 600 kHz, convex, down-facing, 4-beam Janus, the mission's beam angle; no water
profile (0 cells), bottom track only; no attitude, depth or temperature sensor (the
sensor-source byte 0; their fields 0); sound speed 1500 m/s. A bottom-track range is the
vertical range from the instrument (the slant range times the beam angle's cosine), cm; a
beam without bottom lock, or a ping not in bottom track (a water-track ping: auvsim does
not write the reference layer), has range 0, velocity -32768 and percent good 0; a measured
beam percent good 100. Correlation and amplitude are not simulated: 0, with the screening
thresholds (BC, BA, BE) 0. Clocks start at 2000-01-01 00:00:00 UTC, in hundredths of a
second.

Reading: ``scan`` frames the file itself (every ensemble's length and checksum, its data
types and fixed leader) and refuses, in one line, a file that is not PD0 or is another
instrument's (no bottom track, not a 4-beam Janus Workhorse DVL looking down, coordinates
other than beam or instrument); ensembles that fail their checksum or are cut off are
skipped and counted, never read. After an ensemble that fails (its checksum, or a length
that a corrupt byte sends elsewhere, past the end of the file even), framing resumes at the
next header that frames a whole ensemble with a good checksum; an ensemble is cut off only
where no whole one follows it. The ensembles that passed go to MHKiT's copy of dolfyn
(``mhkit.dolfyn.io.rdi.read_rdi``), a maintained reader, which decodes them.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import math
import os
import struct
import tempfile
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np

from auvsim.data.beams import Mode, beam_matrix, error_velocity, least_squares
from auvsim.data.files import check_not_source, check_out_file, make_parent_dirs, write_bytes
from auvsim.data.recorded import finite_numbers, load_toml, read_description
from auvsim.data.schema import mission_attrs
from auvsim.data.writer import DatasetWriter
from auvsim.errors import ConfigError
from auvsim.physics.earth import normal_gravity

COORDINATES = ("beam", "instrument")
HEADER_ID = b"\x7f\x7f"
FIXED_ID, VARIABLE_ID, BOTTOM_ID = 0x0000, 0x0080, 0x0600
BAD_VELOCITY = -32768  # mm/s
EPOCH = datetime(2000, 1, 1, tzinfo=timezone.utc)  # the written clocks' zero
SOUND_SPEED = 1500  # m/s, the fixed leader's and every variable leader's
FIRMWARE = (51, 41)  # a Workhorse (51.x), whose variable leader has the Y2K clock
# Firmware versions of Workhorse-family DVLs (Workhorse, Navigator), as MHKiT's dolfyn
# names them (``mhkit.dolfyn.io.rdi_defs.adcp_type``).
WORKHORSE_FIRMWARE = frozenset({6, 8, 9, 16, 19, 37, 43, 50, 51, 52, 53})
BEAM_ANGLE_CODE = {15: 0, 20: 1, 30: 2}  # system configuration MSB bits 0-1
FREQUENCY_CODE = 3  # 600 kHz (system configuration LSB bits 0-2)
JANUS_4_BEAM = 0x4  # system configuration MSB bits 4-7
# RDI beam k + 1 is auvsim's beam RDI_BEAM[k]; auvsim's beam j is RDI's AUVSIM_BEAM[j] + 1.
RDI_BEAM = np.array([3, 1, 0, 2])
AUVSIM_BEAM = np.argsort(RDI_BEAM)
# auvsim's DVL frame (x forward, y starboard, z down) -> RDI's instrument frame (X from
# beam 1 to beam 2 = auvsim's beam 1 azimuth, 135 deg; Y from beam 4 to beam 3 = beam 0
# azimuth, 45 deg; Z up, toward the face of a down-looking head).
_H = math.sqrt(0.5)
RDI_FROM_DVL = np.array([[-_H, _H, 0.0], [_H, _H, 0.0], [0.0, 0.0, -1.0]])

_FIXED = struct.Struct("<HBBBBBBBBHHHBBBBH3BBhhBBHHBBBBH8sHBBIB")
_VARIABLE = struct.Struct("<HH7BBHHHHhhHh3B3B8sIHIIB8B")
_BOTTOM = struct.Struct("<HHHBBBBHI4H4h4B4B4BHHH4h4B4B4BH4BB4BI")
assert (_FIXED.size, _VARIABLE.size, _BOTTOM.size) == (59, 65, 85)


# ---- writing -------------------------------------------------------------------------


@dataclass(frozen=True)
class Pings:
    """One mission's DVL pings, as PD0 holds them.

    Attributes:
        time: (N,) s from the mission's start.
        beam_velocity: (N, 4) m/s, auvsim's beam order, NaN where not measured.
        beam_range: (N, 4) slant range, m, NaN where none.
        velocity_ls: (N, 3) m/s, auvsim's DVL frame, NaN where none.
        error_velocity: (N,) m/s, auvsim's sign, NaN where none.
        bottom: (N,) bool, the ping is in bottom track.
        beam_angle_deg: the beams' angle from the DVL's axis.
        max_range: m, the bottom track's maximum (0: not stated).
        simulated: the pings are a simulator's (PD0's simulated-data flag), not a log's.
    """

    time: np.ndarray
    beam_velocity: np.ndarray
    beam_range: np.ndarray
    velocity_ls: np.ndarray
    error_velocity: np.ndarray
    bottom: np.ndarray
    beam_angle_deg: float
    max_range: float = 0.0
    simulated: bool = True


def encode(pings: Pings, *, coordinates: str = "beam") -> bytes:
    """The pings as PD0 ensembles (see the module docstring for what is written).

    Raises:
        ConfigError: ``coordinates`` is not beam or instrument; the beam angle is not
            15, 20 or 30 deg; a time is negative or beyond the clock (2099).
    """
    if coordinates not in COORDINATES:
        raise ConfigError(f": expected one of {', '.join(COORDINATES)}, got {coordinates!r}",
                          argument="coordinates")
    angle = round(pings.beam_angle_deg)
    if angle not in BEAM_ANGLE_CODE or abs(angle - pings.beam_angle_deg) > 1e-9:
        raise ConfigError(f"the mission's beam angle is {pings.beam_angle_deg:g} deg; PD0's "
                          "system configuration holds 15, 20 or 30 deg", argument="dataset")
    hundredths = np.round(np.asarray(pings.time) * 100).astype(np.int64)
    if len(hundredths) and (hundredths.min() < 0 or hundredths.max() >= 99 * 365 * 8640000):
        raise ConfigError("the mission's DVL clock runs outside 0 s to 99 years; expected "
                          "times PD0's clock can hold", argument="dataset")
    ok = (pings.bottom[:, None] & np.isfinite(pings.beam_velocity)
          & np.isfinite(pings.beam_range))
    if coordinates == "beam":
        velocity = _mm(np.where(ok, pings.beam_velocity, np.nan))[:, RDI_BEAM]
    else:
        v = np.where(pings.bottom[:, None], pings.velocity_ls, np.nan)
        rdi = -(v @ RDI_FROM_DVL.T)
        e = -np.where(pings.bottom, pings.error_velocity, np.nan)
        velocity = _mm(np.column_stack([rdi, e]))
        velocity[(velocity[:, :3] == BAD_VELOCITY).any(axis=1), :3] = BAD_VELOCITY
    cos = math.cos(math.radians(pings.beam_angle_deg))
    vertical = np.where(ok, np.round(pings.beam_range * cos * 100), 0)
    ranges = np.clip(vertical, 0, 2**24 - 1).astype(np.int64)[:, RDI_BEAM]
    good = np.where(ok, 100, 0)[:, RDI_BEAM]
    fixed = _fixed_leader(angle, coordinates, pings.simulated)
    offsets = (12, 12 + _FIXED.size, 12 + _FIXED.size + _VARIABLE.size)
    length = offsets[-1] + _BOTTOM.size + 2  # the two reserved bytes before the checksum
    header = struct.pack("<2sHBB3H", HEADER_ID, length, 0, 3, *offsets)
    out = bytearray()
    for i, t in enumerate(hundredths.tolist()):
        body = (header + fixed + _variable_leader(i + 1, int(t))
                + _bottom_track(velocity[i], ranges[i], good[i], pings.max_range) + b"\0\0")
        out += body + struct.pack("<H", sum(body) & 0xFFFF)
    return bytes(out)


def _mm(values: np.ndarray) -> np.ndarray:
    """m/s -> int16 mm/s, NaN -> -32768 (beyond +-32.767 m/s: clipped)."""
    mm = np.clip(np.round(np.nan_to_num(values, nan=0.0) * 1000), -32767, 32767)
    return np.where(np.isfinite(values), mm, BAD_VELOCITY).astype(np.int64)


def _fixed_leader(angle: int, coordinates: str, simulated: bool) -> bytes:
    system = (0x40 | 0x08 | FREQUENCY_CODE, JANUS_4_BEAM << 4 | BEAM_ANGLE_CODE[angle])
    ex = 0b00000 if coordinates == "beam" else 0b01010  # instrument, 3-beam solutions
    return _FIXED.pack(
        FIXED_ID, *FIRMWARE, *system,
        int(simulated),  # the simulated-data flag
        # No water profile: 0 cells and pings (a 1 m cell length, which readers divide
        # by); the time between pings 0, the bottom-track pings set the pace.
        0, 4, 0, 0, 100,  # lag, beams, cells, pings, cell length cm
        0, 1, 0, 0, 0, 0,  # blank, profiling mode, correlation min, code reps, %good, BE
        0, 0, 0, ex,
        4500, 0,  # heading alignment 45.00 deg (beam 3 to starboard), bias
        0, 0,  # sensor source and sensors available: none
        0, 0, 0, 0, 0, 0, 0,  # bin 1, pulse, reference layer, false target, spare, lag
        b"\0" * 8, 0, 255, 0, 0, angle)


def _variable_leader(number: int, hundredths: int) -> bytes:
    t = EPOCH + timedelta(milliseconds=10 * hundredths)
    clock = (t.year % 100, t.month, t.day, t.hour, t.minute, t.second, t.microsecond // 10000)
    return _VARIABLE.pack(
        VARIABLE_ID, number & 0xFFFF, *clock, (number >> 16) & 0xFF, 0, SOUND_SPEED,
        0, 0, 0, 0, 35, 0,  # depth, heading, pitch, roll, salinity, temperature
        0, 0, 0, 0, 0, 0, b"\0" * 8, 0, 0, 0, 0, 0,
        t.year // 100, *clock)


def _bottom_track(velocity: np.ndarray, ranges: np.ndarray, good: np.ndarray,
                  max_range: float) -> bytes:
    return _BOTTOM.pack(
        BOTTOM_ID, 1, 0, 0, 0, 0, 5, 0, 0,
        *(ranges & 0xFFFF).tolist(), *velocity.tolist(), *[0] * 8, *good.tolist(),
        0, 0, 0, *[BAD_VELOCITY] * 4, *[0] * 12,
        min(round(max_range * 10), 65535), *[0] * 4, 0, *(ranges >> 16).tolist(), 0)


def export_pd0(dataset: str | os.PathLike, out: str | os.PathLike, *,
               mission: str | None = None, coordinates: str = "beam") -> dict[str, object]:
    """Write one mission's DVL pings as a PD0 file (under a temporary name, renamed when
    whole).

    Args:
        dataset: an auvsim dataset.
        out: the PD0 file to write (its folder made if missing).
        mission: the mission's name (default: the dataset's only one).
        coordinates: beam or instrument (the fixed leader's EX byte says which).

    Returns:
        ``mission``, ``ensembles``, ``bytes`` and ``coordinates`` written.
    """
    from auvsim.data.reader import open_dataset

    check_not_source(out, dataset)  # said as such, before it is another kind's file
    out = check_out_file(out, "PD0", ".pd0", HEADER_ID)
    if coordinates not in COORDINATES:
        raise ConfigError(f": expected one of {', '.join(COORDINATES)}, got {coordinates!r}",
                          argument="coordinates")
    with open_dataset(dataset) as ds:
        m = ds.mission(mission)  # a PD0 file holds one DVL's pings
        mission = m.name
        if not m.has("dvl") or "beam_velocity" not in m.dvl:
            has = ("its DVL's velocity only" if m.has("dvl") and "velocity_ls" in m.dvl
                   else "no DVL")
            raise ConfigError(f"{dataset}: mission {mission!r} has {has}; expected a "
                              "mission with its DVL's beams (dvl/beam_velocity), which a "
                              "PD0 file holds")
        pings = _pings(m)
    data = encode(pings, coordinates=coordinates)
    try:
        make_parent_dirs(out.parent)  # removed again by a command that then fails
    except OSError as e:
        raise ConfigError(f"{str(out)!r}: cannot write there ({e.strerror or e}); expected "
                          "a path in a writable folder", argument="out") from None
    write_bytes(out, data)
    return {"mission": mission, "ensembles": len(pings.time), "bytes": len(data),
            "coordinates": coordinates}


def _pings(m) -> Pings:
    dvl = m.dvl
    beams = np.asarray(dvl.beam_velocity, dtype=float)
    fields = {f"dvl/{k}" for k in dvl}
    valid = (np.asarray(dvl.valid, dtype=bool) if "dvl/valid" in fields
             else np.isfinite(beams))
    beams = np.where(valid, beams, np.nan)
    n = len(beams)
    ranges = (np.asarray(dvl.beam_range, dtype=float) if "dvl/beam_range" in fields
              else np.full((n, 4), np.nan))
    angle = float(m.attrs["beam_angle_deg"])
    h = beam_matrix(math.radians(angle))
    bottom, none = int(Mode.BOTTOM_TRACK), int(Mode.NO_VELOCITY)
    mode = (np.asarray(dvl.mode) if "dvl/mode" in fields
            else np.where(np.isfinite(beams).sum(axis=1) >= 3, bottom, none))
    velocity = (np.asarray(dvl.velocity_ls, dtype=float) if "dvl/velocity_ls" in fields
                else least_squares(beams, h))
    error = (np.asarray(dvl.error_velocity, dtype=float) if "dvl/error_velocity" in fields
             else error_velocity(beams, h))
    return Pings(np.asarray(dvl.time, dtype=float), beams, ranges, velocity, error,
                 mode == bottom, angle, float(m.attrs.get("dvl_max_range", 0.0)),
                 simulated=m.origin == "simulated")


# ---- reading -------------------------------------------------------------------------


@dataclass(frozen=True)
class Scan:
    """What framing a PD0 file found.

    Attributes:
        ensembles: (start, end) byte spans of the ensembles that passed (checksum
            included), in file order.
        bad_checksum: ensembles skipped for a checksum that does not match where their
            length puts it, or a length past the end of the file that a whole ensemble
            follows (a corrupt length).
        truncated: 1 if the file ends inside an ensemble (skipped), else 0.
        skipped_bytes: bytes outside any ensemble that passed.
        coordinates: beam or instrument, from the fixed leader.
        beam_angle_deg: from the fixed leader.
    """

    ensembles: list[tuple[int, int]]
    bad_checksum: int
    truncated: int
    skipped_bytes: int
    coordinates: str
    beam_angle_deg: float


def scan(data: bytes, *, where: str = "PD0 file") -> Scan:
    """Frame ``data`` into ensembles and check that it is a Workhorse DVL's PD0.

    Raises:
        ConfigError: not PD0 (no ensemble with a valid checksum), or another instrument's
            (see the module docstring), in one line.
    """
    if data[:2] != HEADER_ID:
        raise ConfigError(f"{where}: starts with {data[:4].hex() or 'nothing'}, not PD0's "
                          "header 7f7f; expected a Teledyne RDI PD0 file")
    good: list[tuple[int, int]] = []
    bad = 0
    failed_until = pos = 0
    # The bad count before the first ensemble since the last good one that runs past the
    # end: its length is corrupt if a good ensemble follows, else the file is cut off there.
    cut: int | None = None
    while (pos := data.find(HEADER_ID, pos)) >= 0:
        length = int.from_bytes(data[pos + 2:pos + 4], "little")
        end = pos + length + 2
        within = pos + 4 <= len(data) and end <= len(data)
        if within and length >= 6 and (sum(data[pos:pos + length]) & 0xFFFF
                                        == int.from_bytes(data[end - 2:end], "little")):
            good.append((pos, end))
            pos, cut = end, None
            continue
        if pos >= failed_until:  # a header inside a failed ensemble is not another
            if not within and cut is None:
                cut = bad
            bad += 1
            failed_until = end if within and length >= 6 else pos + 2
        pos += 2
    truncated = int(cut is not None)
    if cut is not None:  # what failed from there on is the cut-off ensemble's
        bad = cut
    if not good:
        headers = data.count(HEADER_ID)
        if headers > 1:
            raise ConfigError(f"{where}: no whole ensemble: none of its {headers} headers "
                              "frames one with a good checksum (lengths or checksums "
                              "corrupt); expected a Teledyne RDI PD0 file")
        what = "fails its checksum" if bad else "is cut off"
        raise ConfigError(f"{where}: no whole ensemble (its first {what}); expected a "
                          "Teledyne RDI PD0 file")
    kinds = {_check_ensemble(data, span, where) for span in good}
    if len(kinds) > 1:
        raise ConfigError(f"{where}: its ensembles change configuration ({sorted(kinds)}); "
                          "expected one instrument's, in one coordinate system")
    coordinates, angle = kinds.pop()
    skipped = len(data) - sum(b - a for a, b in good)
    return Scan(good, bad, truncated, skipped, coordinates, angle)


def _check_ensemble(data: bytes, span: tuple[int, int], where: str) -> tuple[str, float]:
    """The ensemble's coordinates and beam angle, once it is known to be a Workhorse DVL's
    bottom-track ensemble (its data types, its fixed leader)."""
    start, end = span
    length = end - start - 2
    count = data[start + 5]
    if 6 + 2 * count > length:
        raise ConfigError(f"{where}: the ensemble at byte {start} lists {count} data types "
                          "beyond its length; expected a PD0 header")
    offsets = struct.unpack_from(f"<{count}H", data, start + 6)
    ids = [int.from_bytes(data[start + o:start + o + 2], "little") if o + 2 <= length else -1
           for o in offsets]
    named = ", ".join(f"{i:04x}" for i in ids)
    for needed, what in ((FIXED_ID, "fixed leader"), (VARIABLE_ID, "variable leader"),
                         (BOTTOM_ID, "bottom track")):
        if needed not in ids:
            raise ConfigError(f"{where}: the ensemble at byte {start} has data types {named}, "
                              f"no {what} ({needed:04x}); expected a Workhorse DVL's "
                              "bottom-track ensembles")
    fixed = start + offsets[ids.index(FIXED_ID)]
    if fixed + 59 > start + length:
        raise ConfigError(f"{where}: the ensemble at byte {start} has a short fixed leader; "
                          "expected a Workhorse's")
    firmware, lsb, msb, beams, ex = (data[fixed + 2], data[fixed + 4], data[fixed + 5],
                                     data[fixed + 8], data[fixed + 25])
    if firmware not in WORKHORSE_FIRMWARE:
        raise ConfigError(f"{where}: firmware {firmware}.{data[fixed + 3]} is not a "
                          "Workhorse's or a Navigator's; expected a Workhorse DVL's PD0 "
                          f"(firmware {', '.join(map(str, sorted(WORKHORSE_FIRMWARE)))})")
    if beams != 4 or msb >> 4 != JANUS_4_BEAM:
        raise ConfigError(f"{where}: the fixed leader says {beams} beams, Janus code "
                          f"{msb >> 4:04b}; expected a 4-beam Janus DVL (0100)")
    if lsb & 0x80:
        raise ConfigError(f"{where}: the fixed leader says the head faces up; expected a "
                          "DVL looking down at the seafloor")
    system = (ex >> 3) & 3
    if system > 1:
        raise ConfigError(f"{where}: velocities in {('ship', 'earth')[system - 2]} "
                          "coordinates (EX bits 3-4); expected beam or instrument "
                          "coordinates (auvsim has no attitude for the others)")
    code = msb & 3
    angle = float({v: k for k, v in BEAM_ANGLE_CODE.items()}.get(code, data[fixed + 58]))
    if not 0 < angle < 90:
        raise ConfigError(f"{where}: beam angle {angle:g} deg; expected 15, 20, 25 or 30")
    return COORDINATES[system], angle


@dataclass(frozen=True)
class Pd0Log:
    """A PD0 file read: its pings in auvsim's DVL frame and what framing skipped.

    Attributes:
        time: (N,) s since 1970 (the instrument's clock, UTC as recorded).
        beam_velocity: (N, 4) m/s, auvsim's beam order, NaN where not measured (beam
            coordinates; None in instrument coordinates).
        beam_range: (N, 4) slant range, m, NaN where none.
        velocity_ls: (N, 3) m/s, auvsim's DVL frame, NaN where none.
        error_velocity: (N,) m/s, auvsim's sign, NaN where none.
        valid: (N, 4) bool, percent good above 0 and a velocity.
        scan: the framing (``Scan``).
    """

    time: np.ndarray
    beam_velocity: np.ndarray | None
    beam_range: np.ndarray
    velocity_ls: np.ndarray
    error_velocity: np.ndarray
    valid: np.ndarray
    scan: Scan


def read_pd0(path: str | os.PathLike) -> Pd0Log:
    """Read a Workhorse DVL's PD0 file: framed and checked by ``scan``, the ensembles that
    passed decoded by MHKiT's dolfyn.

    Raises:
        ConfigError: the file is missing, not PD0, another instrument's, or MHKiT is not
            installed (one line each).
    """
    path = Path(path)
    where = repr(str(path))
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise ConfigError(f"{where}: no such file; expected a PD0 file") from None
    except IsADirectoryError:
        raise ConfigError(f"{where}: a folder; expected a PD0 file") from None
    found = scan(data, where=where)
    if len(found.ensembles) < 2:
        raise ConfigError(f"{where}: {len(found.ensembles)} whole ensemble; expected a "
                          "stream of pings (at least 2)")
    read_rdi = _dolfyn()
    with tempfile.TemporaryDirectory(prefix="auvsim-pd0-") as folder:
        clean = Path(folder) / "ensembles.pd0"
        # dolfyn reads an ensemble only when another's header follows it
        # (``_RDIReader.check_eof``): the last goes in twice, and its copy is not read.
        last = data[slice(*found.ensembles[-1])]
        clean.write_bytes(b"".join(data[a:b] for a, b in found.ensembles) + last)
        with contextlib.redirect_stdout(io.StringIO()), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                ds = read_rdi(str(clean), userdata=False)
            except Exception as e:  # the reader's own refusal, whatever its type
                raise ConfigError(f"{where}: MHKiT's dolfyn cannot decode it ({type(e).__name__}"
                                  f": {' '.join(str(e).split())[:160]}); expected a Workhorse "
                                  "DVL's PD0") from None
    if ds.sizes["time"] != len(found.ensembles):
        raise ConfigError(f"{where}: MHKiT's dolfyn decoded {ds.sizes['time']} of its "
                          f"{len(found.ensembles)} whole ensembles; expected a Workhorse "
                          "DVL's PD0")
    time = ds["time"].values.astype("datetime64[ns]").astype(np.int64) / 1e9
    vel = np.asarray(ds["vel_bt"].values, dtype=float).T  # (N, 4)
    vel[vel < (BAD_VELOCITY + 0.5) / 1000] = np.nan  # -32768 mm/s, in float32 m/s
    good = np.asarray(ds["prcnt_gd_bt"].values).T > 0
    vertical = np.asarray(ds["dist_bt"].values, dtype=float).T
    cos = math.cos(math.radians(found.beam_angle_deg))
    h = beam_matrix(math.radians(found.beam_angle_deg))
    if found.coordinates == "beam":
        valid = (good & np.isfinite(vel) & (vertical > 0))[:, AUVSIM_BEAM]
        beams = np.where(valid, vel[:, AUVSIM_BEAM], np.nan)
        velocity = least_squares(beams, h)
        error = error_velocity(beams, h)
    else:
        valid = (good & (vertical > 0))[:, AUVSIM_BEAM]
        beams = None
        velocity = -(vel[:, :3] @ RDI_FROM_DVL)  # R is orthogonal: R^-1 = R^T
        error = -vel[:, 3]
    ranges = np.where(valid, vertical[:, AUVSIM_BEAM] / cos, np.nan)
    return Pd0Log(time, beams, ranges, velocity, error, valid, found)


def _dolfyn():
    try:
        from mhkit.dolfyn.io.rdi import read_rdi
    except ImportError as e:
        raise ConfigError(f"reading PD0 needs MHKiT (its dolfyn), which is not installed ({e});"
                          " pip install 'auvsim[io]'") from None
    return read_rdi


# ---- the import ----------------------------------------------------------------------


DESCRIPTION_KEYS = {"log": {"name", "origin"},
                    "dvl": {"position_body", "mounting_rpy_deg", "noise_std",
                            "velocity_accuracy"}}


def parse_description(text: str, *, where: str) -> dict:
    """A PD0 log description (TOML): what the file cannot say. ``[log]`` ``origin = [lat
    deg, lon deg, height m]`` (required: the mission's place, whose normal gravity the
    dataset states) and ``name``; ``[dvl]`` ``noise_std`` and ``velocity_accuracy`` (m/s,
    the instrument's figures, required: auvsim invents none), ``position_body`` (m, FRD)
    and ``mounting_rpy_deg`` (deg, ZYX, auvsim's DVL frame -> body), default zeros.

    Raises:
        ConfigError: not TOML, or a key missing, unknown or of the wrong kind.
    """
    data = load_toml(text, where=where)
    for table in data:
        if table not in DESCRIPTION_KEYS or not isinstance(data[table], dict):
            raise ConfigError(f"{where}: unknown table [{table}]; a PD0 log description "
                              "has [log] and [dvl]")
        unknown = sorted(set(data[table]) - DESCRIPTION_KEYS[table])
        if unknown:
            raise ConfigError(f"{where}: {table}.{unknown[0]}: unknown key; expected "
                              f"{', '.join(sorted(DESCRIPTION_KEYS[table]))}")
    log, dvl = data.get("log", {}), data.get("dvl", {})
    out = {"name": log.get("name"),
           "origin": finite_numbers(where, "log.origin", log.get("origin"), 3),
           "position_body": finite_numbers(where, "dvl.position_body",
                                     dvl.get("position_body", [0.0] * 3), 3),
           "mounting_rpy_deg": finite_numbers(where, "dvl.mounting_rpy_deg",
                                        dvl.get("mounting_rpy_deg", [0.0] * 3), 3)}
    if out["name"] is not None and not isinstance(out["name"], str):
        raise ConfigError(f"{where}: log.name: expected a text, got {out['name']!r}")
    for key in ("noise_std", "velocity_accuracy"):
        value = dvl.get(key)
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not math.isfinite(value) or value < 0:
            raise ConfigError(f"{where}: dvl.{key}: expected the instrument's figure, m/s "
                              f">= 0 (auvsim invents none), got {value!r}")
        out[key] = float(value)
    return out


def import_pd0(sources: Sequence[str | os.PathLike], out: str | os.PathLike, *,
               description: str | os.PathLike, compression: str = "lzf"
               ) -> dict[str, dict]:
    """Write a dataset with one recorded mission (``dvl/`` only) per PD0 file; every file
    is read and checked before anything is written.

    Returns:
        Each mission's ``{"dvl": (pings, rate Hz), "bad_checksum": n, "truncated": n,
        "coordinates": ...}``, by name.
    """
    if not sources:
        raise ConfigError(": expected at least one PD0 file", argument="sources")
    if description is None:
        raise ConfigError(": missing; --format pd0 needs a log description (TOML: [log] "
                          "origin, [dvl] noise_std and velocity_accuracy)",
                          argument="description")
    text = read_description(description)
    spec = parse_description(text, where=str(description))
    logs = [(Path(s), read_pd0(s)) for s in sources]
    names = [spec["name"] if spec["name"] and len(sources) == 1 else p.stem for p, _ in logs]
    if len(set(names)) != len(names):
        raise ConfigError(f"mission names must differ, got {names}; rename a file")
    for (path, log) in logs:
        if len(log.time) < 2:
            raise ConfigError(f"{str(path)!r}: {len(log.time)} whole ensemble(s); expected a "
                              "stream of pings (at least 2)")
        back = np.flatnonzero(np.diff(log.time) <= 0)
        if len(back):
            k = int(back[0])
            raise ConfigError(f"{str(path)!r}: ensemble {k + 2} of {len(log.time)} is stamped "
                              f"{log.time[k + 1] - log.time[k]:+.2f} s after the one before; "
                              "expected a clock that increases (two files joined?)")
    lat, lon, height = spec["origin"]
    settings = dict(format="pd0", sources=[str(s) for s in sources],
                    description=str(description))
    summary: dict[str, dict] = {}
    with DatasetWriter(out, config_json=json.dumps({"import": settings}),
                       compression=compression) as writer:
        for name, (path, log) in zip(names, logs, strict=True):
            t0 = float(log.time[0])
            t = log.time - t0
            fields = {"dvl/time": t, "dvl/velocity_ls": log.velocity_ls,
                      "dvl/beam_range": log.beam_range, "dvl/valid": log.valid,
                      "dvl/error_velocity": log.error_velocity,
                      "dvl/mode": np.where(np.isfinite(log.velocity_ls).all(axis=1), 0, -1)}
            if log.beam_velocity is not None:
                fields["dvl/beam_velocity"] = log.beam_velocity
            rate = 1.0 / float(np.median(np.diff(t)))
            attrs = mission_attrs(
                origin="recorded", scenario="recorded", seed=0, duration_s=float(t[-1]),
                groups=json.dumps(["dvl"]), latitude_deg=lat, longitude_deg=lon,
                height_m=height, gravity=normal_gravity(lat, height), log_description=text,
                source_files=json.dumps([str(path)]),
                source_sha256=json.dumps([hashlib.sha256(path.read_bytes()).hexdigest()]),
                log_time_origin_s=t0, dvl_rate_hz=rate,
                beam_angle_deg=log.scan.beam_angle_deg,
                dvl_position_body=np.array(spec["position_body"]),
                dvl_mounting_rpy_deg=np.array(spec["mounting_rpy_deg"]),
                dvl_noise_std=spec["noise_std"],
                dvl_velocity_accuracy=spec["velocity_accuracy"], dvl_time_offset_s=0.0,
                dvl_beams_derived=int(log.beam_velocity is None))
            sink = writer.mission(name, attrs, rows={"dvl": len(t)})
            sink.append(fields)
            sink.flush()
            summary[name] = {"dvl": (len(t), rate), "bad_checksum": log.scan.bad_checksum,
                             "truncated": log.scan.truncated,
                             "coordinates": log.scan.coordinates}
    return summary


__all__ = ["Pings", "Scan", "Pd0Log", "encode", "export_pd0", "scan", "read_pd0",
           "import_pd0", "parse_description"]
