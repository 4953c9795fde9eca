"""MCAP export speed: a `navigator` mission exported as a ROS 2 bag, against generating it.

Generates one `navigator` mission (the preset's sensors, one mission) of ``--duration``
seconds, then exports it with ``auvsim export --to mcap`` once per chunk compression
(zstd, the default, lz4 and none), all in this process, and prints the CPU seconds of
each, the export/generate ratio, the file sizes, each compression's ratio (the
uncompressed bag's size over the file's) and the messages written. Generation and
exports alternate over ``--repeats`` rounds; medians are reported. Then:

- the peak memory of an export: the peak resident set (``VmHWM``) of a fresh
  interpreter that exports the mission (default compression), and of one that only
  imports what the export imports (the difference is the export's own);
- the chunk compressions on this bag's data: the uncompressed bag cut in 1 MiB pieces
  (about a chunk each) compressed with zstd level 1 (the default), zstd level 3 (the
  library's default) and lz4: ratio and CPU seconds;
- the per-message way, for comparison: ``--per-message`` IMU messages written one call a
  message with mcap-ros2-support's ``Writer.write_message`` (encode + write), and their
  CDR payloads with mcap's ``Writer.add_message`` alone, in us a message, and what the
  whole mission would cost that way against generating it (an estimate: the IMU's cost
  a message times every message).

Target: the one-hour mission exports (default compression) in at most 2x the CPU time it
took to generate.

    .venv/bin/python benchmarks/export.py [--duration 3600] [--repeats 1]
        [--per-message 20000] [--write]
"""

from __future__ import annotations

import argparse
import dataclasses
import io
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import perf_page

from auvsim.interop.ros2 import COMPRESSIONS, export_mcap
from auvsim.runs.generate import generate
from auvsim.runs.presets import preset


def cpu_seconds(fn) -> tuple[float, object]:
    start = time.process_time()
    result = fn()
    return time.process_time() - start, result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=3600.0, help="mission length, s")
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--per-message", type=int, default=20000,
                        help="IMU messages written one call at a time")
    perf_page.add_write_option(parser, "export")
    args = parser.parse_args()

    config = preset("navigator")
    first = config.missions[0]
    config = dataclasses.replace(config, missions=(dataclasses.replace(
        first, scenario=dataclasses.replace(first.scenario, duration=args.duration)),))
    times: dict[str, list[float]] = {"generate": [], **{c: [] for c in COMPRESSIONS}}
    with tempfile.TemporaryDirectory() as tmp:
        h5 = Path(tmp) / "navigator.h5"
        generate(config, h5, workers=1, progress=False)  # numba's cache loaded once
        sizes, counts = {}, {}
        for _ in range(args.repeats):
            h5.unlink()
            times["generate"].append(cpu_seconds(
                lambda: generate(config, h5, workers=1, progress=False))[0])
            for c in COMPRESSIONS:
                out = Path(tmp) / f"navigator-{c}.mcap"
                seconds, counts = cpu_seconds(lambda c=c, out=out: export_mcap(
                    h5, out, compression=c))
                times[c].append(seconds)
                sizes[c] = out.stat().st_size / 1e6
        h5_mb = h5.stat().st_size / 1e6
        peak, baseline = peak_rss_mb(h5, Path(tmp) / "peak.mcap")
        pieces = chunk_compression(Path(tmp) / "navigator-none.mcap")
        per_message = one_call_a_message(h5, args.per_message)
    med = {k: statistics.median(v) for k, v in times.items()}
    total = sum(counts.values())
    print(f"navigator mission of {args.duration:g} s: {total} messages ("
          + ", ".join(f"{t} {n}" for t, n in counts.items())
          + f"); median of {args.repeats} (CPU seconds)")
    print(f"{'':16s} {'CPU s':>8s} {'x generate':>11s} {'us/message':>11s} {'MB':>8s}")
    print(f"{'generate':16s} {med['generate']:8.2f} {1:11.2f} {'':>11s} {h5_mb:8.1f}")
    for c in COMPRESSIONS:
        print(f"{'export ' + c:16s} {med[c]:8.2f} {med[c] / med['generate']:11.2f} "
              f"{med[c] / total * 1e6:11.2f} {sizes[c]:8.1f}  "
              f"{sizes['none'] / sizes[c]:.2f}x smaller than none")
    print(f"peak memory (VmHWM) of an export (zstd) in a fresh interpreter: {peak:.0f} MB; "
          f"of one that only imports: {baseline:.0f} MB; the export's own: "
          f"{peak - baseline:.0f} MB")
    print("chunk compression of the uncompressed bag in 1 MiB pieces (ratio, CPU s):")
    for name, (ratio, seconds) in pieces.items():
        print(f"  {name:8s} {ratio:5.2f}x  {seconds:6.3f} s")
    encode_us, add_us = per_message
    estimate = (encode_us * total / 1e6) / med["generate"]
    print(f"one call a message ({args.per_message} IMU messages): mcap_ros2 "
          f"Writer.write_message {encode_us:.1f} us, mcap Writer.add_message alone "
          f"{add_us:.2f} us; the whole mission that way ~{encode_us * total / 1e6:.1f} CPU s "
          f"= ~{estimate:.1f}x generate (estimate)")
    ratio = med["zstd"] / med["generate"]
    print(f"target: export (zstd, the default) <= 2x generate -> {ratio:.2f}x, "
          f"{'met' if ratio <= 2 else 'MISSED'}")


def peak_rss_mb(h5: Path, out: Path) -> tuple[float, float]:
    """The peak resident set, MB, of a fresh interpreter exporting ``h5`` (default
    compression), and of one that imports the same modules and does nothing: each child
    prints its ``VmHWM`` (/proc/self/status, kB) at its end. Not ``ru_maxrss``: Linux
    keeps it across ``execve``, so a child would report this process's peak."""
    imports = ("import mcap.records, mcap_ros2.writer, zstandard, h5py, numpy; "
               "from auvsim.interop.ros2 import export_mcap; ")
    report = ("; print(next(line.split()[1] for line in open('/proc/self/status') "
              "if line.startswith('VmHWM')))")
    peaks = []
    for work in (f"export_mcap({str(h5)!r}, {str(out)!r})", "None"):
        done = subprocess.run([sys.executable, "-c", imports + work + report], check=True,
                              capture_output=True, text=True)
        peaks.append(int(done.stdout.split()[-1]) / 1024)
    return peaks[0], peaks[1]


def chunk_compression(bag: Path) -> dict[str, tuple[float, float]]:
    """Ratio and CPU seconds of each chunk compression on the bytes of an uncompressed
    bag, in 1 MiB pieces."""
    import lz4.frame
    import zstandard

    data = bag.read_bytes()
    pieces = [data[i:i + (1 << 20)] for i in range(0, len(data), 1 << 20)]
    ways = {"zstd-1": zstandard.ZstdCompressor(level=1).compress,
            "zstd-3": zstandard.ZstdCompressor(level=3).compress,
            "lz4": lz4.frame.compress}
    out = {}
    for name, compress in ways.items():
        seconds, packed = cpu_seconds(lambda compress=compress: sum(
            len(compress(p)) for p in pieces))
        out[name] = (len(data) / packed, seconds)
    return out


def one_call_a_message(h5: Path, n: int) -> tuple[float, float]:
    """us a message of mcap_ros2's ``Writer.write_message`` (encode and write) and of
    mcap's ``Writer.add_message`` (write a payload), on the first ``n`` IMU samples."""
    from mcap.reader import make_reader
    from mcap.writer import Writer as McapWriter
    from mcap_ros2.writer import Writer

    from auvsim.data.reader import open_dataset
    from auvsim.interop import rosmsg

    with open_dataset(h5) as ds:
        imu = next(iter(ds.missions.values())).imu
        t, w, f = imu.time[:n], imu.angular_rate[:n], imu.specific_force[:n]
    messages = []
    for k in range(len(t)):
        sec, nanosec = divmod(round(t[k] * 1e9), 1_000_000_000)
        messages.append({
            "header": {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": "imu_link"},
            "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
            "orientation_covariance": [-1.0] + [0.0] * 8,
            "angular_velocity": dict(zip("xyz", map(float, w[k]), strict=True)),
            "angular_velocity_covariance": [0.0] * 9,
            "linear_acceleration": dict(zip("xyz", map(float, f[k]), strict=True)),
            "linear_acceleration_covariance": [0.0] * 9})
    buffer = io.BytesIO()
    writer = Writer(buffer)
    schema = writer.register_msgdef("sensor_msgs/msg/Imu",
                                    rosmsg.schema_text("sensor_msgs/msg/Imu"))
    encode_s, _ = cpu_seconds(lambda: [writer.write_message(
        "/imu/data", schema, m, log_time=i) for i, m in enumerate(messages)])
    writer.finish()
    buffer.seek(0)
    payloads = [m.data for _, _, m in make_reader(buffer).iter_messages()]
    plain = McapWriter(io.BytesIO())
    plain.start()
    channel = plain.register_channel("/imu/data", "cdr", plain.register_schema(
        "sensor_msgs/msg/Imu", "ros2msg", b""))
    add_s, _ = cpu_seconds(lambda: [plain.add_message(
        channel, log_time=i, data=p, publish_time=i) for i, p in enumerate(payloads)])
    plain.finish()
    return encode_s / len(messages) * 1e6, add_s / len(payloads) * 1e6


if __name__ == "__main__":
    sys.exit(perf_page.run(main))
