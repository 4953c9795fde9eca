"""What a grid seafloor costs in ``auvsim generate``, against the procedural one.

The ``navigator`` preset's mission (its survey lines off Haifa, every DVL effect), shortened
to ``--duration`` seconds, is generated over its procedural terrain and over a bathymetry
grid of similar relief (60 m deep, 1 m std, 25 m features) that this script writes as a
GeoTIFF around the preset's location, at a survey's spacing (1/9 arc-second, about 3.4 m:
a heightmap of about 1200 x 1200 vertices over the default 4 km ``seafloor.extent``) and at
GEBCO's (15 arc-seconds, about 460 m). The runs alternate, procedural then each grid, for
``--rounds`` rounds, in this process with one worker; each is timed in CPU seconds
(``time.process_time``: every thread of the process) and the grid's heightmap is read
afresh each time (its per-process cache cleared). The ratio of the medians is the
grid's cost; the target is at most 1.2.

``generate`` also hashes the whole grid file (its SHA-256 goes into the stored config), so
a large grid costs its size over the hashing speed, however small the area it uses: that
speed is measured last, on a file of ``--hash-mb`` MB read through ``grid_sha256`` from the
page cache (wall seconds, median of 3 reads; from a disk, the disk's own read speed caps
it), and priced for a global GEBCO file of 7 GB.

    .venv/bin/python benchmarks/seafloor_grid.py [--duration 300] [--rounds 5] [--write]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import perf_page

from auvsim.config import SeafloorConfig
from auvsim.runs.generate import generate
from auvsim.runs.presets import preset
from auvsim.world.grid import clear_cache, grid_sha256

ARCSEC = 1.0 / 3600.0
GEBCO_BYTES = 7e9  # a global GEBCO grid file


def write_grid(path: Path, latitude: float, longitude: float, step_deg: float) -> Path:
    """A GeoTIFF of elevations about 2.4 km each way around a place: 60 m deep, a 1 deg
    slope, and 1 m std of random relief with features of about 25 m (a sum of waves)."""
    import rasterio
    from rasterio.transform import Affine

    dlon = step_deg / math.cos(math.radians(latitude))
    k = math.ceil(2400.0 / (step_deg * 111_000))
    lats = latitude + np.arange(k, -k - 1, -1) * step_deg
    lons = longitude + np.arange(-k, k + 1) * dlon
    north = (lats - latitude)[:, None] * 111_000.0
    east = (lons - longitude)[None, :] * 111_000.0 * math.cos(math.radians(latitude))
    rng = np.random.default_rng(0)
    waves = 40
    k_vec = rng.normal(scale=1 / 25.0, size=(waves, 2)) * 2 * np.pi  # rad/m
    phase = rng.uniform(0, 2 * np.pi, waves)
    relief = sum(np.cos(k_vec[w, 0] * north + k_vec[w, 1] * east + phase[w])
                 for w in range(waves)) * math.sqrt(2.0 / waves)
    depth = 60.0 + math.tan(math.radians(1.0)) * north + relief
    transform = Affine(dlon, 0.0, lons[0] - dlon / 2, 0.0, -step_deg, lats[0] + step_deg / 2)
    with rasterio.open(path, "w", driver="GTiff", height=len(lats), width=len(lons), count=1,
                       dtype="float32", crs="EPSG:4326", transform=transform) as ds:
        ds.write((-depth).astype(np.float32), 1)
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=300.0, help="mission s")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--hash-mb", type=int, default=256,
                        help="size of the file whose SHA-256 speed is measured, MB")
    perf_page.add_write_option(parser, "seafloor_grid")
    args = parser.parse_args()
    procedural = preset("navigator").with_duration(args.duration)
    place = procedural.location
    # Over a grid the current's power law needs its water depth: the procedural plane's.
    water = dataclasses.replace(procedural.water, water_depth=procedural.seafloor.depth)
    with tempfile.TemporaryDirectory() as folder:
        configs = {"procedural": procedural}
        for name, step in (("survey 1/9 arcsec", ARCSEC / 9), ("GEBCO 15 arcsec", 15 * ARCSEC)):
            path = write_grid(Path(folder) / f"{step:.8f}.tif", place.latitude_deg,
                              place.longitude_deg, step)
            configs[name] = dataclasses.replace(
                procedural, water=water, seafloor=SeafloorConfig(kind="grid", grid=str(path)))
        out = Path(folder) / "x.h5"
        for config in configs.values():  # untimed: numba's cache loads, first calls
            generate(config.with_duration(10.0), out, workers=1, progress=False)
        seconds: dict[str, list[float]] = {name: [] for name in configs}
        for _ in range(args.rounds):
            for name, config in configs.items():
                clear_cache()  # read the grid afresh, as a new run does
                start = time.process_time()
                generate(config, out, workers=1, progress=False)
                seconds[name].append(time.process_time() - start)
        hashing = hash_speed(Path(folder) / "hash.bin", args.hash_mb)
    base = statistics.median(seconds["procedural"])
    print(f"navigator, {args.duration:g} s mission, {args.rounds} alternating rounds, "
          "CPU s (median):")
    for name, values in seconds.items():
        median = statistics.median(values)
        print(f"  {name:18s} {median:7.2f} s   x{median / base:.3f} of procedural, "
              f"{median - base:+.2f} s   "
              f"({' '.join(f'{v:.2f}' for v in values)})")
    print(f"SHA-256 of a {args.hash_mb} MB file (grid_sha256, page cache, median of 3): "
          f"{hashing:.0f} MB/s; a 7 GB global GEBCO file adds "
          f"{GEBCO_BYTES / 1e6 / hashing:.0f} s to every generate")


def hash_speed(path: Path, megabytes: int) -> float:
    """MB/s of ``grid_sha256`` over a file of ``megabytes`` MB of random bytes, read from the
    page cache (wall seconds, median of 3 reads after one that warms the cache)."""
    rng = np.random.default_rng(0)
    with open(path, "wb") as f:
        for _ in range(megabytes):
            f.write(rng.bytes(1_000_000))
    grid_sha256(path)
    seconds = []
    for _ in range(3):
        start = time.perf_counter()
        grid_sha256(path)
        seconds.append(time.perf_counter() - start)
    os.remove(path)
    return megabytes / statistics.median(seconds)


if __name__ == "__main__":
    sys.exit(perf_page.run(main))
