"""The seafloor: what MuJoCo ray-casts is the terrain the config describes, and depth_at
is that same surface."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from auvsim.config import SeafloorConfig
from auvsim.errors import ConfigError
from auvsim.world.seafloor import GROUP, Seafloor

MODEL = Path(__file__).resolve().parent.parent / "models" / "auv.xml"
DOWN = np.array([0.0, 0.0, 1.0])


def scene(seafloor: Seafloor, *, vehicle_ned=(0.0, 0.0, 10.0), hull_group: int | None = None):
    """The vehicle model with the seafloor, the vehicle level at ``vehicle_ned``."""
    spec = mujoco.MjSpec.from_file(str(MODEL))
    if hull_group is not None:
        spec.geom("hull").group = hull_group
    seafloor.attach(spec)
    model = spec.compile()
    data = mujoco.MjData(model)
    data.qpos[:3] = np.asarray(vehicle_ned) * [1, -1, -1]
    data.qpos[3:7] = [1, 0, 0, 0]
    mujoco.mj_forward(model, data)
    seafloor.bind(model, data)
    return model, data, model.body("vehicle").id


def cast(seafloor, model, data, origins, directions, *, max_range=1000.0, exclude=-1):
    origins = np.atleast_2d(np.asarray(origins, dtype=float))
    directions = np.asarray(directions, dtype=float).reshape(len(origins), -1, 3)
    return seafloor.cast(model, data, origins, directions, max_range=max_range,
                         exclude_body=exclude)


def beam(angle_deg: float, azimuth_deg: float) -> np.ndarray:
    """Unit NED vector ``angle_deg`` from straight down, towards ``azimuth_deg``."""
    a, z = math.radians(angle_deg), math.radians(azimuth_deg)
    return np.array([math.sin(a) * math.cos(z), math.sin(a) * math.sin(z), math.cos(a)])


def procedural(seed=0, **kw) -> Seafloor:
    settings = dict(kind="procedural", depth=60.0, roughness=2.0, correlation_length=20.0,
                    slope_deg=5.0, slope_heading_deg=30.0, cell_size=2.0)
    settings.update(kw)
    return Seafloor(SeafloorConfig(**settings), rng=np.random.default_rng(seed))


def random_points(n: int, half: float, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    pts = np.random.default_rng(seed).uniform(-half, half, (n, 2))
    return pts[:, 0], pts[:, 1]


def hits_agree(seafloor, model, data, north, east, *, height=30.0, angle=30.0):
    """Cast a vertical and four slanted beams from ``height`` above the terrain at each
    point; return the largest disagreement with depth_at, m (the vertical range must be
    ``height``, each slanted hit must lie on depth_at's surface)."""
    origins = np.column_stack([north, east, seafloor.depth_at(north, east) - height])
    beams = np.stack([DOWN] + [beam(angle, az) for az in (45, 135, 225, 315)])
    directions = np.broadcast_to(beams, (len(origins), 5, 3))
    ranges = cast(seafloor, model, data, origins, directions)
    assert np.isfinite(ranges).all()
    hits = origins[:, None, :] + ranges[..., None] * directions
    surface = seafloor.depth_at(hits[..., 0], hits[..., 1])
    return max(np.abs(ranges[:, 0] - height).max(), np.abs(hits[..., 2] - surface).max())


# -- flat --------------------------------------------------------------------------------

def test_flat_ranges_are_the_geometry_of_a_plane():
    floor = Seafloor(SeafloorConfig(kind="flat", depth=100.0))
    model, data, _ = scene(floor)
    origin = [50.0, -30.0, 20.0]
    assert cast(floor, model, data, origin, DOWN)[0, 0] == pytest.approx(80.0, abs=1e-12)
    for angle, azimuth in ((30, 0), (35, 60), (60, 250)):
        r = cast(floor, model, data, origin, beam(angle, azimuth))[0, 0]
        assert r == pytest.approx(80.0 / math.cos(math.radians(angle)), rel=1e-12)
    # Beyond max_range, or pointing up: no bottom.
    assert np.isnan(cast(floor, model, data, origin, DOWN, max_range=79.0)[0, 0])
    assert np.isnan(cast(floor, model, data, origin, beam(60, 0), max_range=159.0)[0, 0])
    assert np.isnan(cast(floor, model, data, origin, -DOWN)[0, 0])
    np.testing.assert_array_equal(floor.depth_at(np.zeros((2, 3)), np.arange(3.0)),
                                  np.full((2, 3), 100.0))


def test_flat_seafloor_is_group_3_without_contacts():
    floor = Seafloor(SeafloorConfig(kind="flat", depth=100.0))
    model, _, _ = scene(floor)
    geom = model.geom("seafloor")
    assert (geom.group[0], geom.contype[0], geom.conaffinity[0]) == (GROUP, 0, 0)
    assert geom.type[0] == mujoco.mjtGeom.mjGEOM_PLANE


# -- the vehicle -------------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["flat", "procedural"])
def test_beam_from_inside_the_hull_sees_the_floor_not_the_hull(kind):
    floor = (Seafloor(SeafloorConfig(kind="flat", depth=100.0)) if kind == "flat"
             else procedural())
    # The hull in the seafloor's group, so only the body exclusion keeps it out of view.
    model, data, vehicle = scene(floor, vehicle_ned=(0.0, 0.0, 30.0), hull_group=GROUP)
    inside = [0.0, 0.0, 30.0]
    expected = floor.depth_at(0.0, 0.0) - 30.0
    assert cast(floor, model, data, inside, DOWN, exclude=vehicle)[0, 0] == pytest.approx(
        expected, abs=1e-6)
    # Without the exclusion the beam stops at the hull's skin, 0.25 m below its axis.
    assert cast(floor, model, data, inside, DOWN)[0, 0] == pytest.approx(0.25, abs=1e-9)


# -- procedural --------------------------------------------------------------------------

def test_procedural_terrain_is_determined_by_its_rng():
    north, east = random_points(2000, 450.0)
    first = procedural(seed=7).depth_at(north, east)
    np.testing.assert_array_equal(procedural(seed=7).depth_at(north, east), first)
    assert np.abs(procedural(seed=8).depth_at(north, east) - first).max() > 2.0


def test_procedural_terrain_has_the_configured_slope_roughness_and_correlation():
    roughness, length, slope, heading = 2.0, 20.0, 5.0, 30.0
    floor = procedural(roughness=roughness, correlation_length=length, slope_deg=slope,
                       slope_heading_deg=heading)
    north, east = random_points(40000, 500.0)
    depth = floor.depth_at(north, east)
    design = np.column_stack([np.ones_like(north), north, east])
    (d0, grad_n, grad_e), *_ = np.linalg.lstsq(design, depth, rcond=None)
    tan = math.tan(math.radians(slope))
    assert grad_n == pytest.approx(tan * math.cos(math.radians(heading)), abs=2e-3)
    assert grad_e == pytest.approx(tan * math.sin(math.radians(heading)), abs=2e-3)
    assert d0 == pytest.approx(60.0, abs=0.5)
    exact_plane = 60.0 + tan * (north * math.cos(math.radians(heading))
                                + east * math.sin(math.radians(heading)))
    residual = depth - exact_plane
    assert np.std(residual) == pytest.approx(roughness, rel=0.1)
    # Correlation exp(-r^2 / length^2): 1/e one correlation length away.
    shifted = floor.depth_at(north + length, east) - (exact_plane + tan * length
                                                      * math.cos(math.radians(heading)))
    ok = np.isfinite(shifted)
    rho = np.corrcoef(residual[ok], shifted[ok])[0, 1]
    assert rho == pytest.approx(math.exp(-1), abs=0.08)


@pytest.mark.parametrize("cell_size", [2.0, 0.7])
def test_procedural_grid_points_are_the_formula(cell_size):
    floor = procedural(cell_size=cell_size)
    c = floor.config
    i, j = np.meshgrid(np.arange(-200, 201, 7), np.arange(-200, 201, 9), indexing="ij")
    noise = floor._noise[-np.arange(len(floor._noise)) % len(floor._noise)].T  # (north, east)
    n_noise = noise.shape[0]
    tan = math.tan(math.radians(c.slope_deg))
    psi = math.radians(c.slope_heading_deg)
    north, east = i * c.cell_size, j * c.cell_size
    expected = (c.depth + tan * (north * math.cos(psi) + east * math.sin(psi))
                + c.roughness * noise[i % n_noise, j % n_noise])
    # Up to the float32 in which MuJoCo stores the heights.
    np.testing.assert_allclose(floor.depth_at(north, east), expected, rtol=0, atol=1e-5)


def test_depth_at_is_the_surface_mujoco_casts():
    floor = procedural(slope_deg=10.0, slope_heading_deg=200.0)
    model, data, _ = scene(floor)
    north, east = random_points(400, 480.0)
    assert hits_agree(floor, model, data, north, east) < 1e-6


def test_follow_recentres_the_window_continuously():
    floor = procedural()
    model, data, _ = scene(floor)
    far_n, far_e = np.array([7000.0, 7010.0]), np.array([-7000.0, -6990.0])
    assert np.isnan(floor.depth_at(far_n, far_e)).all()
    assert np.isnan(cast(floor, model, data, [7000.0, -7000.0, 0.0], DOWN)[0, 0])

    # A point still in the window after a short move keeps its depth (to float32).
    north, east = random_points(1000, 150.0)
    before = floor.depth_at(north + 200.0, east)
    floor.follow(np.array([[500.0, 0.0]]), reach=100.0)
    assert not np.isnan(floor.depth_at(900.0, 0.0))  # it moved
    after = floor.depth_at(north + 200.0, east)
    np.testing.assert_allclose(after, before, rtol=0, atol=1e-5)

    floor.follow(np.column_stack([far_n, far_e]), reach=100.0)
    assert np.isfinite(floor.depth_at(far_n, far_e)).all()
    north, east = random_points(200, 100.0)
    assert hits_agree(floor, model, data, north + 7000.0, east - 7000.0) < 1e-6
    # Still the configured plane out there (5 deg towards 030).
    plane = 60.0 + math.tan(math.radians(5.0)) * (7000 * math.cos(math.radians(30))
                                                  - 7000 * math.sin(math.radians(30)))
    assert np.mean(floor.depth_at(north + 7000.0, east - 7000.0)) == pytest.approx(
        plane, abs=2.0)


def test_follow_refuses_what_no_window_can_hold():
    floor = procedural()
    with pytest.raises(ValueError, match="terrain window"):
        floor.follow(np.array([[0.0, 0.0], [2000.0, 0.0]]), reach=100.0)


def test_procedural_needs_an_rng():
    with pytest.raises(ValueError, match="rng"):
        Seafloor(SeafloorConfig(kind="procedural", roughness=1.0))


# -- heightmap ---------------------------------------------------------------------------

def tilted(rows: int, cols: int, cell: float) -> np.ndarray:
    """Depths 50 + 0.1 n - 0.05 e on a (north, east) grid centred on (0, 0)."""
    n = (np.arange(rows) - (rows - 1) / 2) * cell
    e = (np.arange(cols) - (cols - 1) / 2) * cell
    return 50.0 + 0.1 * n[:, None] - 0.05 * e[None, :]


@pytest.mark.parametrize("rows, cols", [(31, 21), (303, 203)])  # one tile; 2 x 3, padded
def test_heightmap_is_cast_where_it_is_and_nowhere_else(tmp_path, rows, cols):
    path = tmp_path / "map.npy"
    np.save(path, tilted(rows, cols, 2.0))
    floor = Seafloor(SeafloorConfig(kind="heightmap", heightmap=str(path), cell_size=2.0))
    model, data, _ = scene(floor)
    half_n, half_e = (rows - 1), (cols - 1)  # m, at 2 m cells
    rng = np.random.default_rng(3)
    north = rng.uniform(-0.7, 0.7, 300) * half_n
    east = rng.uniform(-0.7, 0.7, 300) * half_e
    np.testing.assert_allclose(floor.depth_at(north, east), 50 + 0.1 * north - 0.05 * east,
                               rtol=0, atol=1e-5)
    assert hits_agree(floor, model, data, north, east, height=10.0, angle=20.0) < 1e-6
    origins = np.column_stack([north, east, np.zeros_like(north)])
    vertical = cast(floor, model, data, origins, np.broadcast_to(DOWN, (300, 1, 3)))[:, 0]
    np.testing.assert_allclose(vertical, 50 + 0.1 * north - 0.05 * east, rtol=0, atol=1e-5)

    # Outside: nothing, including just past the north edge (where any padding is).
    outside_n = np.array([half_n + 0.5, 0.0, -half_n - 3.0, 0.0])
    outside_e = np.array([0.0, half_e + 0.5, 0.0, -half_e - 50.0])
    assert np.isnan(floor.depth_at(outside_n, outside_e)).all()
    origins = np.column_stack([outside_n, outside_e, np.zeros(4)])
    assert np.isnan(cast(floor, model, data, origins, np.broadcast_to(DOWN, (4, 1, 3)))).all()
    # A beam from beside the map, below its edge, would hit the hfield's side wall.
    side = cast(floor, model, data, [0.0, half_e + 5.0, 60.0], beam(60.0, 270.0))
    assert np.isnan(side).all()


@pytest.mark.parametrize("content, found", [
    (None, "no such file"),
    (np.arange(10.0), "shape (10,)"),
    (np.array([[1.0, 2.0], [np.nan, 3.0]]), "1 non-finite"),
    (b"not numpy", "numpy cannot read"),
])
def test_bad_heightmap_files_are_config_errors_naming_the_file(tmp_path, content, found):
    path = tmp_path / "bad_map.npy"
    if isinstance(content, bytes):
        path.write_bytes(content)
    elif content is not None:
        np.save(path, content)
    with pytest.raises(ConfigError) as err:
        Seafloor(SeafloorConfig(kind="heightmap", heightmap=str(path)))
    message = str(err.value)
    assert str(path) in message and found in message and "\n" not in message


# -- the compiled queries ----------------------------------------------------------------

def numpy_surface(floor: Seafloor, north: np.ndarray, east: np.ndarray):
    """``depth_at`` and ``normal_at`` as numpy computed them before they were compiled
    (auvsim 7b6258e), the reference the compiled loops must match bit for bit."""
    x, y = np.broadcast_arrays(np.asarray(north, dtype=float), -np.asarray(east, dtype=float))
    x_lo, x_hi, y_lo, y_hi = floor._cover
    inside = (x >= x_lo) & (x <= x_hi) & (y >= y_lo) & (y <= y_hi)
    x, y = np.where(inside, x, x_lo), np.where(inside, y, y_lo)
    (rows, cols), (n_a, n_b), cell = floor._tile_cells, floor._tiles, floor.cell
    a = np.clip(((y - floor._origin[1]) // (rows * cell)).astype(np.intp), 0, n_a - 1)
    b = np.clip(((x - floor._origin[0]) // (cols * cell)).astype(np.intp), 0, n_b - 1)
    pos = floor._tile_pos[a, b]
    hx, hy = floor._half
    u = (x - pos[..., 0] + hx) / (2.0 * hx / cols)
    v = (y - pos[..., 1] + hy) / (2.0 * hy / rows)
    c = np.clip(np.floor(u), 0, cols - 1).astype(np.intp)
    r = np.clip(np.floor(v), 0, rows - 1).astype(np.intp)
    fu, fv = u - c, v - r
    flat = floor._heights.ravel()
    k = ((a * n_b + b) * (rows + 1) + r) * (cols + 1) + c
    h00, h11 = flat[k].astype(float), flat[k + cols + 2].astype(float)
    upper = fu >= fv
    side = np.where(upper, flat[k + 1], flat[k + cols + 1]).astype(float)
    big, small = np.where(upper, fu, fv), np.where(upper, fv, fu)
    height = h00 + (side - h00) * big + (h11 - side) * small
    depth = np.where(inside, -(pos[..., 2] + height * floor._elevation[a, b]), np.nan)
    dh_du = np.where(upper, side - h00, h11 - side)
    dh_dv = np.where(upper, h11 - side, side - h00)
    elevation = floor._elevation[a, b]
    d_north = -elevation * dh_du * cols / (2.0 * hx)
    d_east = elevation * dh_dv * rows / (2.0 * hy)
    normal = np.stack([d_north, d_east, -np.ones_like(d_north)], axis=-1)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    return depth, np.where(inside[..., None], normal, np.nan)


def test_the_compiled_depth_and_normal_are_numpys_bit_for_bit(tmp_path):
    path = tmp_path / "map.npy"
    np.save(path, tilted(303, 203, 2.0) + np.random.default_rng(4).normal(0, 0.3, (303, 203)))
    floors = [procedural(), procedural(slope_deg=10.0, cell_size=0.5), procedural(seed=3),
              Seafloor(SeafloorConfig(kind="heightmap", heightmap=str(path), cell_size=2.0))]
    floors[2].follow(np.array([[3000.0, -2000.0]]), reach=100.0)  # a recentred window
    rng = np.random.default_rng(5)
    for floor in floors:
        x_lo, x_hi, y_lo, y_hi = floor._cover
        # Random points, inside and outside; the grid's vertices, cell edges and tile
        # seams themselves, and a hair either side; the cover's edges; NaN and infinity.
        north = rng.uniform(x_lo - 20, x_hi + 20, 20000)
        east = -rng.uniform(y_lo - 20, y_hi + 20, 20000)
        grid_n = x_lo + floor.cell * rng.integers(0, round((x_hi - x_lo) / floor.cell) + 1, 5000)
        grid_e = -(y_lo + floor.cell * rng.integers(0, round((y_hi - y_lo) / floor.cell) + 1,
                                                    5000))
        hair = rng.choice([-1e-9, 0.0, 1e-9], (2, 5000))
        north = np.r_[north, grid_n + hair[0], grid_n, x_lo, x_hi, x_lo, np.nan, np.inf, 0.0]
        east = np.r_[east, grid_e + hair[1], -rng.uniform(y_lo, y_hi, 5000), -y_lo, -y_hi,
                     np.nan, 0.0, 0.0, -np.inf]
        depth, normal = numpy_surface(floor, north, east)
        assert floor.depth_at(north, east).tobytes() == depth.tobytes()
        assert floor.normal_at(north, east).tobytes() == normal.tobytes()
        assert np.isfinite(depth).sum() > 20000  # mostly inside
        # Any broadcastable shapes, scalars included, as before.
        grid = (north[:12].reshape(3, 4), east[:4])
        assert floor.depth_at(*grid).tobytes() == numpy_surface(floor, *grid)[0].tobytes()
        assert floor.normal_at(*grid).tobytes() == numpy_surface(floor, *grid)[1].tobytes()
        one = floor.depth_at(float(north[0]), float(east[0]))
        assert one.shape == () and one.tobytes() == numpy_surface(
            floor, north[0], east[0])[0].tobytes()


def test_follow_recentres_exactly_when_numpy_said_it_must():
    floor = procedural()
    rng = np.random.default_rng(6)
    inner = (floor._m - 1) * floor.cell
    outcomes = set()
    for _ in range(400):
        centre = np.array(floor._centre) * floor.cell
        # Points whose reach ends within a few 1e-13 m of the window's kept edge.
        edge = centre + rng.choice([-1, 1], 2) * inner
        reach = float(rng.choice([0.0, 37.5, 90.0 * math.sin(math.radians(30))]))
        points = edge - np.sign(edge - centre) * reach + rng.normal(0, 1e-13, (3, 2))
        lo, hi = points.min(axis=0) - reach, points.max(axis=0) + reach
        stays = bool(np.all(lo >= centre - inner) and np.all(hi <= centre + inner))
        before = floor._centre
        floor.follow(points, reach=reach)
        assert (floor._centre == before) == stays
        outcomes.add(stays)
    assert outcomes == {False, True}
    with pytest.raises(ValueError, match="non-finite"):
        floor.follow(np.array([[0.0, np.nan]]), reach=10.0)
    with pytest.raises(ValueError, match="reach"):
        floor.follow(np.zeros((1, 2)), reach=math.inf)


def test_a_flat_floors_compiled_altitude_is_numpys():
    floor = Seafloor(SeafloorConfig(kind="flat", depth=60.0))
    north = np.array([0.0, np.nan, 1.0, np.inf, -3.0, 5.0])
    east = np.array([1.0, 2.0, np.nan, 0.0, -np.inf, -0.0])
    down = np.array([20.0, 1.0, -0.0, 3.5, np.nan, 61.25])
    expected = np.where(np.isfinite(north) & np.isfinite(east), 60.0, np.nan) - down
    assert floor.depth_at(north, east).tobytes() == (expected + down).tobytes()
    position = np.column_stack([north, east, down])
    assert floor.altitude(position).tobytes() == expected.tobytes()
    assert floor.altitude(position[::2]).tobytes() == expected[::2].tobytes()
