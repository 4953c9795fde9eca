"""``seafloor.kind = "grid"``: a georeferenced bathymetry grid (GeoTIFF, NetCDF) gives the
DVL the analytic ranges of the seafloor it describes, and bad grids are refused.

The grids are written here, sampled at their own points' local NED positions (through
``ned_from_geodetic``, independent of the ``geodetic_from_ned`` the loader places the
heightmap with). The known answer: from a beam origin o (NED) along a unit direction u,
the plane ``depth(n, e) = d0 + gn n + ge e`` is reached after

    t = (d0 + gn o_n + ge o_e - o_d) / (u_d - gn u_n - ge u_e),

the altitude over the plane below o divided by the beam's rate of closing on it.
"""

from __future__ import annotations

import hashlib
import json
import math

import mujoco
import numpy as np
import pytest

rasterio = pytest.importorskip("rasterio")
xr = pytest.importorskip("xarray")

from rasterio.transform import Affine  # noqa: E402

from auvsim.cli import main  # noqa: E402
from auvsim.config import (  # noqa: E402
    Config,
    LocationConfig,
    MissionConfig,
    ScenarioConfig,
    SeafloorConfig,
)
from auvsim.data.beams import beam_matrix  # noqa: E402
from auvsim.data.reader import open_dataset  # noqa: E402
from auvsim.errors import ConfigError  # noqa: E402
from auvsim.physics.earth import geodetic_from_ned, ned_from_geodetic  # noqa: E402
from auvsim.physics.frames import rotation_matrices, rotation_rpy  # noqa: E402
from auvsim.runs.generate import generate  # noqa: E402
from auvsim.world.grid import clear_cache, load_grid  # noqa: E402
from auvsim.world.seafloor import Seafloor  # noqa: E402

HERE = (32.8498, 34.8922)  # latitude, longitude, deg: off Haifa
PLANE = (60.0, 0.05, -0.03)  # d0 m, gn, ge: 60 m deep at the origin, 2.9 and 1.7 deg
ARCSEC = 1.0 / 3600.0


def plane(north, east):
    d0, gn, ge = PLANE
    return d0 + gn * north + ge * east


def step(north, east):
    """50 m south of the origin's parallel, 58 m north of it."""
    return np.where(north < 0, 50.0, 58.0)


def grid_points(step_deg: float, half_m: float):
    """Latitudes (north to south) and longitudes (west to east) of pixel centres about
    ``half_m`` around HERE, about ``step_deg`` apart (east spacing about the north one),
    with HERE exactly on a pixel centre."""
    lat0, lon0 = HERE
    dlon = step_deg / math.cos(math.radians(lat0))
    k_lat, k_lon = (math.ceil(half_m / (d * 111_000)) for d in (step_deg, step_deg))
    lats = lat0 + np.arange(k_lat, -k_lat - 1, -1) * step_deg
    lons = lon0 + np.arange(-k_lon, k_lon + 1) * dlon
    return lats, lons, step_deg, dlon


def sample(depth_of, lats, lons) -> np.ndarray:
    """(lat, lon) grid of depths, m, of ``depth_of(north, east)`` at the points' NED."""
    la, lo = np.meshgrid(lats, lons, indexing="ij")
    ned = ned_from_geodetic(la.ravel(), lo.ravel(), np.zeros(la.size), (*HERE, 0.0))
    return depth_of(ned[:, 0], ned[:, 1]).reshape(la.shape)


def write_geotiff(path, depth_of, *, step_deg=3 * ARCSEC, half_m=800.0, crs="EPSG:4326",
                  holes=(), nodata=-32768.0):
    """A GeoTIFF of elevations (GEBCO's sign: negative below sea level), north up."""
    lats, lons, dlat, dlon = grid_points(step_deg, half_m)
    elevation = -sample(depth_of, lats, lons)
    for r, c in holes:
        elevation[r, c] = nodata
    transform = Affine(dlon, 0.0, lons[0] - dlon / 2, 0.0, -dlat, lats[0] + dlat / 2)
    with rasterio.open(path, "w", driver="GTiff", height=len(lats), width=len(lons), count=1,
                       dtype="float32", crs=crs, transform=transform, nodata=nodata) as ds:
        ds.write(elevation.astype(np.float32), 1)
    return path


def write_netcdf(path, depth_of, *, step_deg=3 * ARCSEC, half_m=800.0, holes=(),
                 lat_attrs=None, mapping=None, uneven=False):
    """A CF NetCDF of elevations on latitude (south to north, as GEBCO's) and longitude;
    ``uneven``: latitudes spaced unevenly, up to 30 % of a step off the even ones."""
    lats, lons, _, _ = grid_points(step_deg, half_m)
    lats = lats[::-1]
    if uneven:
        lats = lats + 0.3 * step_deg * np.sin(np.arange(len(lats)) * 1.3)
    elevation = -sample(depth_of, lats, lons)
    for r, c in holes:
        elevation[r, c] = np.nan
    lat_attrs = {"units": "degrees_north", "standard_name": "latitude"} \
        if lat_attrs is None else lat_attrs
    attrs = {"units": "m", "positive": "up"}
    variables = {}
    if mapping is not None:
        attrs["grid_mapping"] = "crs"
        variables["crs"] = ((), np.int32(0), mapping)
    ds = xr.Dataset({"elevation": (("lat", "lon"), elevation, attrs), **variables},
                    coords={"lat": ("lat", lats, lat_attrs),
                            "lon": ("lon", lons, {"units": "degrees_east"})})
    ds.to_netcdf(path, encoding={"elevation": {"_FillValue": -9999.0, "dtype": "float32"}})
    return path


def grid_config(path, *, duration=10.0, seed=3, **floor) -> Config:
    scenario = ScenarioConfig(speed=2.0, heading_deg=30.0, depth=20.0, duration=duration)
    return Config(missions=(MissionConfig(scenario=scenario, seed=seed),),
                  seafloor=SeafloorConfig(kind="grid", grid=str(path),
                                          **{"extent": 1000.0, **floor}),
                  location=LocationConfig(*HERE))


def plane_ranges(origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """(K, B) slant ranges to PLANE from (K, 3) origins along (K, B, 3) unit directions."""
    d0, gn, ge = PLANE
    altitude = d0 + gn * origins[:, 0] + ge * origins[:, 1] - origins[:, 2]
    closing = directions[..., 2] - gn * directions[..., 0] - ge * directions[..., 1]
    return altitude[:, None] / closing


def test_geodetic_from_ned_inverts_ned_from_geodetic():
    ned = np.random.default_rng(0).uniform(-60e3, 60e3, (500, 3)) * [1, 1, 0.01]
    for origin in ((*HERE, 0.0), (-71.0, 179.99, 0.0), (0.0, -180.0, -30.0)):
        place = geodetic_from_ned(ned, origin)
        back = ned_from_geodetic(place[:, 0], place[:, 1], place[:, 2], origin)
        assert np.abs(back - ned).max() < 1e-8


@pytest.mark.parametrize("kind", ["tif", "nc", "uneven.nc"])
def test_dvl_ranges_over_a_sloping_grid_are_the_planes(tmp_path, kind):
    # A plane sampled at any points, and bilinear between them, is the plane: an unevenly
    # spaced NetCDF axis (fractional indices linear between its points) keeps it too.
    write = {"tif": write_geotiff, "nc": write_netcdf,
             "uneven.nc": lambda *a: write_netcdf(*a, uneven=True)}[kind]
    grid = write(tmp_path / f"slope.{kind}", plane)
    out = tmp_path / "slope.h5"
    generate(grid_config(grid), out, workers=1, progress=False)
    with open_dataset(out) as ds:
        m = ds.missions["mission_000"]
        rows = m.imu.index_of_dvl[:]
        ranges = m.dvl.beam_range[:].astype(float)
        position, quaternion = m.truth.position_ned[:][rows], m.truth.quaternion[:][rows]
        attrs = m.attrs
    # The DVL's beams: H's rows (beam angle from its axis, azimuths 45 + 90 k deg) turned
    # by its mounting into body axes, then into NED; they start at its lever arm.
    rotation = rotation_matrices(quaternion)
    mounting = rotation_rpy(*np.radians(attrs["dvl_mounting_rpy_deg"]))
    beams_body = beam_matrix(math.radians(attrs["beam_angle_deg"])) @ mounting.T
    directions = np.einsum("mij,kj->mki", rotation, beams_body)
    origins = position + rotation @ np.asarray(attrs["dvl_position_body"])
    expected = plane_ranges(origins, directions)
    assert len(ranges) >= 4 and np.isfinite(ranges).all()
    # float32 on disk (1e-5 m at 60 m) and MuJoCo's float32 heights (1e-6 of a tile's span).
    np.testing.assert_allclose(ranges, expected, rtol=0, atol=5e-4)


def scene(floor: Seafloor):
    """A world with only the seafloor, for ray casts."""
    spec = mujoco.MjSpec()
    floor.attach(spec)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    floor.bind(model, data)
    return model, data


@pytest.mark.parametrize("kind", ["tif", "nc"])
def test_a_step_gives_each_levels_ranges_away_from_its_edge(tmp_path, kind):
    write = write_geotiff if kind == "tif" else write_netcdf
    grid = write(tmp_path / f"step.{kind}", step, step_deg=ARCSEC / 9, half_m=150.0)
    floor = Seafloor(grid_config(grid, extent=200.0).seafloor, location=LocationConfig(*HERE))
    model, data = scene(floor)
    # The step is a ramp one grid spacing wide (bilinear), cut into the lattice's cells.
    margin = 2 * max(floor.cell, ARCSEC / 9 * 111_000)
    h = beam_matrix(math.radians(30.0))
    checked = {50.0: 0, 58.0: 0}
    for north in (-60.0, -25.0, -5.0, 5.0, 25.0, 60.0):
        for roll, pitch, yaw in ((0, 0, 0), (10, -5, 30), (-8, 12, 200)):
            rotation = rotation_rpy(*np.radians([roll, pitch, yaw]))
            origin = np.array([[north, 3.0, 20.0]])
            u = (rotation @ h.T).T[None]
            got = floor.cast(model, data, origin, u, max_range=200.0, exclude_body=-1)[0]
            for level, other in ((50.0, 58.0), (58.0, 50.0)):
                t = (level - origin[0, 2]) / u[0, :, 2]
                t_other = (other - origin[0, 2]) / u[0, :, 2]
                hit, hit_other = origin[0, 0] + t * u[0, :, 0], origin[0, 0] + t_other * u[0, :, 0]
                if level == 50.0:  # reaches the shallow side first
                    mine = hit < -margin
                else:  # passes over the shallow level's depth north of the ramp, and lands
                    mine = (hit > margin) & (hit_other > margin)
                np.testing.assert_allclose(got[mine], t[mine], rtol=0, atol=1e-4)
                checked[level] += int(mine.sum())
    assert min(checked.values()) >= 20


def test_nodata_is_refused_or_filled_from_its_neighbours(tmp_path):
    lats, lons, _, _ = grid_points(3 * ARCSEC, 800.0)
    centre = (len(lats) // 2, len(lons) // 2)
    holes = [(centre[0] + 2, centre[1] - 3), (centre[0] - 3, centre[1] + 2), centre]
    for kind, write in (("tif", write_geotiff), ("nc", write_netcdf)):
        grid = write(tmp_path / f"holes.{kind}", plane, holes=holes)
        location = dict(latitude_deg=HERE[0], longitude_deg=HERE[1])
        with pytest.raises(ConfigError, match=r"has 3 nodata point\(s\)"):
            load_grid(grid_config(grid).seafloor, **location)
        filled = load_grid(grid_config(grid, nodata="fill").seafloor, **location)
        # A single-point hole in a plane takes its 4 neighbours' mean: the plane again.
        rows, cols = filled.depths.shape
        north = filled.corner[0] + np.arange(rows)[:, None] * filled.cell
        east = filled.corner[1] + np.arange(cols)[None, :] * filled.cell
        np.testing.assert_allclose(filled.depths, plane(north, east), rtol=0, atol=2e-5)


def test_the_heightmap_takes_the_grids_spacing_capped_by_the_area(tmp_path):
    grid = write_geotiff(tmp_path / "g.tif", plane, step_deg=3 * ARCSEC, half_m=800.0)
    location = dict(latitude_deg=HERE[0], longitude_deg=HERE[1])
    own = load_grid(grid_config(grid, extent=1000.0).seafloor, **location)
    # 3 arc-seconds of latitude; the east spacing was made equal (3 / cos(lat) of longitude).
    assert own.cell == pytest.approx(3 * ARCSEC * math.pi / 180 * 6_353_000, rel=2e-3)
    assert own.corner == (-math.floor(500 / own.cell) * own.cell,) * 2
    # A wider area than the grid covers: cropped to the grid (about 800 m each way).
    wide = load_grid(grid_config(grid, extent=5000.0).seafloor, **location)
    assert 730 < -wide.corner[0] < 840 and 730 < -wide.corner[1] < 840
    # An area that would need more than 4096 vertices a side at a grid's spacing (3.4 m):
    # coarser, and cropped to the grid (150 m each way).
    fine = write_geotiff(tmp_path / "fine.tif", plane, step_deg=ARCSEC / 9, half_m=150.0)
    coarse = load_grid(grid_config(fine, extent=20_000.0).seafloor, **location)
    assert coarse.cell == pytest.approx(20_000.0 / 4095)
    assert 140 < -coarse.corner[0] < 160 and coarse.depths.shape[0] < 70


def test_a_process_keeps_a_heightmap_until_its_cache_is_cleared(tmp_path):
    grid = write_geotiff(tmp_path / "g.tif", plane)
    floor, location = grid_config(grid).seafloor, dict(latitude_deg=HERE[0],
                                                         longitude_deg=HERE[1])
    first = load_grid(floor, **location)
    assert load_grid(floor, **location) is first  # kept: the grid is not read again
    clear_cache()
    again = load_grid(floor, **location)
    assert again is not first  # read afresh, as a new process reads it
    np.testing.assert_array_equal(again.depths, first.depths)


def test_same_config_and_seed_give_identical_data_and_record_the_grid(tmp_path):
    grid = write_netcdf(tmp_path / "slope.nc", plane)
    config = grid_config(grid, duration=2.0)
    first, second = tmp_path / "a.h5", tmp_path / "b.h5"
    for out in (first, second):
        generate(config, out, workers=1, progress=False)
    with open_dataset(first) as a, open_dataset(second) as b:
        ma, mb = a.missions["mission_000"], b.missions["mission_000"]
        for group in ("dvl", "truth", "imu"):
            for field in getattr(ma, group):
                np.testing.assert_array_equal(getattr(getattr(ma, group), field),
                                              getattr(getattr(mb, group), field))
        text = a.config_json
    stored = json.loads(text)["seafloor"]
    assert stored["grid"] == str(grid)
    assert stored["grid_sha256"] == hashlib.sha256(grid.read_bytes()).hexdigest()
    assert Config.from_json(text).seafloor.grid_sha256 == stored["grid_sha256"]


BAD = {
    "utm": (lambda p: write_geotiff(p / "g.tif", plane, crs="EPSG:32636"),
            "is in CRS 'EPSG:32636'"),
    "nad83": (lambda p: write_geotiff(p / "g.tif", plane, crs="EPSG:4269"),
              "is in CRS 'EPSG:4269'"),
    "no crs": (lambda p: write_geotiff(p / "g.tif", plane, crs=None), "has no georeference"),
    "no lat/lon": (lambda p: write_netcdf(p / "g.nc", plane, lat_attrs={"units": "m"}),
                   "has no georeference"),
    "projected mapping": (lambda p: write_netcdf(p / "g.nc", plane, mapping={
        "grid_mapping_name": "transverse_mercator"}), "grid mapping 'crs'"),
    "hole": (lambda p: write_geotiff(p / "g.tif", plane, holes=[(9, 9)]), "nodata"),
    "far away": (lambda p: write_geotiff(p / "g.tif", lambda n, e: n * 0 + 60.0, half_m=100,
                                         ), "), whose latitude is outside"),
    "missing": (lambda p: p / "none.tif", "no such file"),
    "not a grid": (lambda p: (p / "g.txt").write_text("x") and p / "g.txt", "suffix"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_grids_give_one_line_and_exit_2(tmp_path, capfd, monkeypatch, case):
    make, message = BAD[case]
    grid = make(tmp_path)
    latitude = HERE[0] + (0.1 if case == "far away" else 0.0)
    (tmp_path / "c.toml").write_text(
        f'[seafloor]\nkind = "grid"\ngrid = "{grid.name}"\nextent = 1000\n'
        f"[location]\nlatitude_deg = {latitude}\nlongitude_deg = {HERE[1]}\n"
        "[[missions]]\n[missions.scenario]\nduration = 2\n")
    monkeypatch.chdir(tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(["generate", "--config", "c.toml", "--out", "x.h5", "--quiet"]) == 2
    out, err = capfd.readouterr()
    assert err.count("\n") == 1 and err.startswith("auvsim: error: ") and message in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_a_grid_needs_a_location():
    with pytest.raises(ConfigError, match="location"):
        Config(seafloor=SeafloorConfig(kind="grid", grid="g.tif"))
    with pytest.raises(ConfigError, match="seafloor.nodata"):
        SeafloorConfig(kind="grid", grid="g.tif", nodata="zero")


def test_a_changed_grid_is_refused_by_the_config_that_pinned_it(tmp_path):
    grid = write_geotiff(tmp_path / "g.tif", plane)
    config = grid_config(grid, grid_sha256="0" * 64)
    with pytest.raises(ConfigError, match="SHA-256"):
        generate(config, tmp_path / "x.h5", workers=1, progress=False)
    assert not (tmp_path / "x.h5").exists()


@pytest.mark.parametrize("module,suffix", [("rasterio", "tif"), ("xarray", "nc")])
def test_a_missing_reader_names_the_extra_to_install(tmp_path, monkeypatch, module, suffix):
    grid = (write_geotiff if suffix == "tif" else write_netcdf)(tmp_path / f"g.{suffix}", plane)
    monkeypatch.setitem(__import__("sys").modules, module, None)  # import fails
    with pytest.raises(ConfigError, match=rf"needs {module}.*pip install 'auvsim\[io\]'"):
        load_grid(grid_config(grid).seafloor, latitude_deg=HERE[0], longitude_deg=HERE[1])


def test_an_area_across_a_global_grids_seam_is_cut_at_it(tmp_path):
    # A grid registered on its lines, both -180 and 180 deg in it (GEBCO's one-minute one).
    lons = np.linspace(-180.0, 180.0, 21601)
    lats = np.linspace(-0.1, 0.1, 13)
    xr.Dataset({"z": (("lat", "lon"), np.full((13, 21601), -60.0))},
               coords={"lat": ("lat", lats, {"units": "degrees_north"}),
                       "lon": ("lon", lons, {"units": "degrees_east"})}).to_netcdf(
        tmp_path / "world.nc")
    floor = grid_config(tmp_path / "world.nc", extent=4000.0).seafloor
    # 0.001 deg (111 m) west of 180 deg: the heightmap (1 km cells) ends at the origin.
    terrain = load_grid(floor, latitude_deg=0.0, longitude_deg=179.999)
    assert terrain.corner[1] == -2000.0 and terrain.depths.shape == (5, 3)
    np.testing.assert_allclose(terrain.depths, 60.0)
