"""The seafloor: the surface the DVL beams hit, in MuJoCo and as a depth function.

``kind="flat"`` is an infinite plane at ``depth``. ``kind="procedural"`` is seeded random
terrain on a plane that may slope::

    depth(n, e) = depth + tan(slope) (n cos(psi) + e sin(psi)) + roughness * noise(n, e)

with ``psi`` the slope heading (the direction in which it gets deeper) and ``noise`` a
zero-mean, unit-std stationary Gaussian random field with correlation function
``exp(-r^2 / correlation_length^2)``. The field is a periodic tile made once from the rng
by FFT-filtering white noise; at the world grid point ``(i, j) * cell_size`` it is
``tile[i mod N, j mod N]``, so it is defined on the whole plane, and between grid points
the surface is the triangulated one below. MuJoCo ray-casts a fixed-size window of that
grid, recentred by ``Seafloor.follow`` as the vehicle travels. ``kind="heightmap"`` is a
user's grid of depths, fixed. ``kind="grid"`` is a georeferenced bathymetry grid, made
into such a heightmap around the missions' geographic origin by ``auvsim.world.grid``.

Both are held in MuJoCo as a grid of hfield tiles sharing their edge vertices. One hfield
would do, but MuJoCo's ray test visits every cell under the ray's path through the
hfield's whole elevation range, so its cost grows with the square of that range; tiles
each span a fraction of the slope's depth change.

``Seafloor.depth_at`` evaluates exactly the surface MuJoCo ray-casts: the same float32
heights, the same triangulation (MuJoCo splits cell (r, c) of an hfield along the diagonal
from vertex (r, c) to (r + 1, c + 1)), not the analytic formula. Between tiles the
float32 heights of a shared vertex may differ by a few 1e-7 of a tile's elevation range.

Coordinates: NED outside, MuJoCo's north-west-up (x, y) = (north, -east) inside. An
hfield's columns run along x and its rows along y, so the terrain grids below are kept in
MuJoCo's layout: columns northward, rows westward.
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numba
import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from auvsim.config import MAX_DEPTH, LocationConfig, SeafloorConfig
from auvsim.errors import ConfigError
from auvsim.physics.frames import FLIP as _FLIP  # NED <-> MuJoCo's north-west-up, either way

NAME = "seafloor"  # the plane geom; hfield tiles and their geoms are seafloor_<row>_<col>
GROUP = 3  # geom group of the seafloor alone, so ray casts can select it

# Procedural window, square, centred on a grid point. A 60 s block at 4 m/s spans 240 m
# of track, and a beam reaches 90-200 m further out (generate.py passes the DVL's maximum
# range as the reach): 240 + 2 * 200 = 640 m fits in 1024 m, with room for the next block,
# so the window is recentred about every other block. 1024 m is 513 x 513 vertices at the
# default 2 m cells: 1 MB of float32 heights, refilled in about 1 ms. Cells finer than 1 m
# keep that vertex count and shrink the window (0.5 m: 512 m, refilled in about 5 ms).
WINDOW_SIDE = 1024.0  # m, wanted
MAX_WINDOW_CELLS = 1024  # per side
WINDOW_TILES = 4  # per side: 256 m tiles at the default size
# A heightmap is cut into tiles of about this side, at most this many per side: every
# tile costs each ray two box tests.
TILE_SIDE = 256.0  # m
MAX_TILES = 8
# The noise tile's period, in correlation lengths; more costs memory and set-up time only.
TILE_PERIODS = 20
MAX_NOISE_CELLS = 2048  # per side: 32 MB of float64 (and the FFT's scratch) at most
# A heightmap of at most 4096 x 4096 depths: its grid is held about four times over (the
# float64 depths, their padded tiles, the float32 heights and MuJoCo's copy), about 0.5 GB.
MAX_HEIGHTMAP_VERTICES = 4096 * 4096
BASE = 1.0  # m, thickness of the solid box MuJoCo puts under an hfield
EDGE = 1e-6  # m: hits this close to the terrain's edge are on its side walls
_GROUPS = np.zeros(6, dtype=np.uint8)  # the geom groups a cast sees: GROUP alone
_GROUPS[GROUP] = 1



class Seafloor:
    """The terrain under a mission: builds it into a MuJoCo scene and ray-casts against it.

    Typical use::

        seafloor = Seafloor(config.seafloor, rng=rng)
        spec = mujoco.MjSpec.from_file("models/auv.xml")
        seafloor.attach(spec)
        model = spec.compile()
        data = mujoco.MjData(model)
        seafloor.bind(model, data)
        ...
        seafloor.follow(origins[:, :2], reach=max_range)
        ranges = seafloor.cast(model, data, origins, directions, max_range=max_range,
                               exclude_body=model.body("vehicle").id)

    ``depth_at`` and ``follow`` also work without a scene.

    Args:
        config: the seafloor settings.
        rng: source of the procedural terrain (required for ``kind="procedural"``, unused
            otherwise).
        location: the missions' geographic origin (required for ``kind="grid"``, which it
            places on the grid; unused otherwise).

    Raises:
        ConfigError: the heightmap file is missing or is not a 2-D array of finite depths
            within the ocean's depth, of at most ``MAX_HEIGHTMAP_VERTICES``.
            A grid that ``auvsim.world.grid.load_grid`` refuses.
        ValueError: ``kind="procedural"`` without an rng, ``kind="grid"`` without a location.
    """

    def __init__(self, config: SeafloorConfig, *, rng: np.random.Generator | None = None,
                 location: LocationConfig | None = None):
        self.config = config
        self.kind = config.kind
        self.cell = float(config.cell_size)
        self._model: mujoco.MjModel | None = None
        self._data: mujoco.MjData | None = None
        if self.kind == "flat":
            return
        if self.kind == "procedural":
            if not isinstance(rng, np.random.Generator):
                raise ValueError(f"rng: expected a numpy.random.Generator for procedural "
                                 f"terrain, got {rng!r}")
            self._init_procedural(rng)
        elif self.kind == "grid":
            if location is None or not location.given:
                raise ValueError(f"location: expected the missions' latitude and longitude "
                                 f"for a grid seafloor, got {location!r}")
            from auvsim.world.grid import load_grid  # rasterio and xarray, when asked for

            terrain = load_grid(config, latitude_deg=location.latitude_deg,
                                longitude_deg=location.longitude_deg)
            self.cell = terrain.cell
            self._init_heightmap(terrain.depths, corner=terrain.corner)
        else:
            self._init_heightmap(_load_heightmap(config.heightmap))

    # -- terrain ------------------------------------------------------------------------

    def _init_procedural(self, rng: np.random.Generator) -> None:
        c, cell = self.config, self.cell
        per_tile = min(math.ceil(WINDOW_SIDE / WINDOW_TILES / cell),
                       MAX_WINDOW_CELLS // WINDOW_TILES)
        per_tile += per_tile % 2  # even, so the window centre is a grid point
        self._tiles = (WINDOW_TILES, WINDOW_TILES)
        self._tile_cells = (per_tile, per_tile)  # (rows, cols) of cells per tile
        self._m = WINDOW_TILES * per_tile // 2  # window half side, cells
        period = max(math.ceil(TILE_PERIODS * c.correlation_length / cell), 2 * self._m)
        noise = _noise_tile(min(_fast_size(period), MAX_NOISE_CELLS),
                            c.correlation_length / cell, rng)
        # Stored in MuJoCo's layout, so a window is up to four block copies of it: row k is
        # east index -k (mod N), column l north index l.
        self._noise = np.ascontiguousarray(noise.T[-np.arange(len(noise)) % len(noise)])
        slope = math.tan(math.radians(c.slope_deg))
        heading = math.radians(c.slope_heading_deg)
        self._gradient = (slope * math.cos(heading), slope * math.sin(heading))  # per m
        # Depth range of any tile: the plane across it, plus the noise's whole range.
        span = (per_tile * cell * (abs(self._gradient[0]) + abs(self._gradient[1]))
                + c.roughness * float(noise.max() - noise.min()))
        self._elevation = np.full(self._tiles, span if span > 0 else 1.0)
        self._allocate()
        self._window = np.empty((2 * self._m + 1, 2 * self._m + 1))
        self._fill_window(0, 0)

    def _init_heightmap(self, depths: np.ndarray,
                        corner: tuple[float, float] | None = None) -> None:
        """Hold (rows north, cols east) depths whose vertex (0, 0) is at NED ``corner``
        (north, east, m; None: the grid centred on the origin)."""
        grid = depths[:, ::-1].T  # MuJoCo layout: rows westward, columns northward
        cells = np.array(grid.shape) - 1
        tiles = np.minimum(np.ceil(cells * self.cell / TILE_SIDE), MAX_TILES).astype(int)
        per_tile = -(-cells // tiles)
        self._tiles, self._tile_cells = tuple(tiles), tuple(per_tile)
        # Pad the far (west, north) sides to whole tiles; the padding is not seafloor.
        pad = tiles * per_tile - cells
        grid = np.pad(grid, ((0, pad[0]), (0, pad[1])), mode="edge")
        x0, y0 = -cells[1] * self.cell / 2, -cells[0] * self.cell / 2
        if corner is not None:  # x0 north of the south row, y0 west of the east column
            x0, y0 = corner[0], -(corner[1] + cells[0] * self.cell)
        tile_view = _tile_view(grid, self._tile_cells)
        span = tile_view.max(axis=(2, 3)) - tile_view.min(axis=(2, 3))
        self._elevation = np.where(span > 0, span, 1.0)
        self._allocate()
        self._set_terrain(grid, x0, y0, cells * self.cell)
        self._scratch = None  # a heightmap is set once

    def _allocate(self) -> None:
        # The window is refilled in place on every recentring, as fresh megabyte arrays
        # cost more in page faults than the arithmetic.
        shape = (*self._tiles, self._tile_cells[0] + 1, self._tile_cells[1] + 1)
        self._scratch = np.empty(shape)
        self._heights = np.empty(shape, dtype=np.float32)  # per tile, as MuJoCo holds them

    def _fill_window(self, ci: int, cj: int) -> None:
        """Centre the procedural window on grid point (ci, cj) (north, east indices)."""
        c, m, cell = self.config, self._m, self.cell
        depth = self._window  # row k: east index cj + m - k; column l: north index ci - m + l
        _copy_wrapped(self._noise, -(cj + m), ci - m, out=depth)
        depth *= c.roughness
        gn, ge = self._gradient
        # The plane relative to the window centre, where it is depth + cell (gn ci + ge cj).
        offset = np.arange(-m, m + 1) * cell
        depth += (c.depth + cell * (gn * ci + ge * cj)) + gn * offset
        depth += (ge * -offset)[:, None]
        self._centre = (ci, cj)
        self._set_terrain(depth, (ci - m) * cell, -(cj + m) * cell, np.full(2, 2 * m * cell))

    def _set_terrain(self, depth: np.ndarray, x0: float, y0: float,
                     extent: np.ndarray) -> None:
        """Cut a grid of depths into hfield tiles and hand them to MuJoCo if bound.

        Args:
            depth: (rows, cols) depths, m, in MuJoCo's layout, a whole number of tiles.
            x0, y0: MuJoCo position of vertex (0, 0), m.
            extent: (y, x) size of the part that is seafloor, m, from vertex (0, 0).
        """
        (rows, cols), cell = self._tile_cells, self.cell
        tiles = _tile_view(depth, self._tile_cells)
        bottom = tiles.max(axis=(2, 3))  # each tile's deepest vertex is its hfield's base
        heights = np.subtract(bottom[:, :, None, None], tiles, out=self._scratch)
        heights /= self._elevation[:, :, None, None]
        np.clip(heights, 0.0, 1.0, out=heights)
        self._heights[...] = heights
        self._half = (cols * cell / 2, rows * cell / 2)  # hfield x, y half sizes, m
        a, b = np.indices(self._tiles)
        self._tile_pos = np.stack([x0 + (2 * b + 1) * self._half[0],
                                   y0 + (2 * a + 1) * self._half[1], -bottom], axis=-1)
        self._origin = (x0, y0)
        self._cover = (x0, x0 + extent[1], y0, y0 + extent[0])  # x and y bounds, m
        if self._model is not None:
            self._upload()

    # -- MuJoCo -------------------------------------------------------------------------

    def attach(self, spec: mujoco.MjSpec) -> None:
        """Add the seafloor to ``spec.worldbody``, before compiling.

        A plane geom named ``"seafloor"`` (flat), or hfield assets and their geoms named
        ``"seafloor_<row>_<col>"``; all in geom group ``GROUP`` and without contacts (they
        exist for ray casts only).
        """
        common = dict(contype=0, conaffinity=0, group=GROUP, rgba=[0.55, 0.5, 0.4, 1.0])
        if self.kind == "flat":
            spec.worldbody.add_geom(name=NAME, type=mujoco.mjtGeom.mjGEOM_PLANE,
                                    size=[0.0, 0.0, 1.0], pos=[0.0, 0.0, -self.config.depth],
                                    **common)
            return
        rows, cols = self._tile_cells
        # Heights are uploaded by bind(); MuJoCo wants data (or a file) to compile. One
        # in-memory file of zeros in MuJoCo's binary hfield format (int32 nrow, int32 ncol,
        # float32 data) serves every tile: passing each tile's zeros as userdata converts
        # them element by element, 70 ms for a 1200 x 1200 heightmap against 10 ms.
        blank = f"{NAME}_blank.bin"
        spec.assets = {**spec.assets, blank: np.array([rows + 1, cols + 1], np.int32).tobytes()
                       + bytes(4 * (rows + 1) * (cols + 1))}
        for a, b in np.ndindex(self._tiles):
            name = f"{NAME}_{a}_{b}"
            spec.add_hfield(name=name, file=blank,
                            size=[*self._half, float(self._elevation[a, b]), BASE])
            spec.worldbody.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_HFIELD,
                                    hfieldname=name, pos=self._tile_pos[a, b], **common)

    def bind(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Remember the compiled model and data, and upload the terrain into them."""
        self._model, self._data = model, data
        if self.kind == "flat":
            self._geoms = np.array([model.geom(NAME).id])
            return
        names = [f"{NAME}_{a}_{b}" for a, b in np.ndindex(self._tiles)]
        self._geoms = np.array([model.geom(name).id for name in names])
        adr = [int(model.hfield_adr[model.hfield(name).id]) for name in names]
        # attach() added them in order, so their heights are one block of hfield_data.
        self._adr = adr[0]
        assert adr == list(range(adr[0], adr[0] + self._heights.size, self._heights[0, 0].size))
        self._upload()

    def _upload(self) -> None:
        """Copy the heights and tile positions into the model, and the positions into the
        data too, so casts see them before the next mj_forward."""
        model, data = self._model, self._data
        model.hfield_data[self._adr:self._adr + self._heights.size] = self._heights.ravel()
        model.geom_pos[self._geoms] = self._tile_pos.reshape(-1, 3)
        data.geom_xpos[self._geoms] = self._tile_pos.reshape(-1, 3)

    def follow(self, north_east: np.ndarray, reach: float) -> None:
        """Make the ray-castable terrain cover every point within ``reach`` of some points.

        Recentres the procedural window when any of them is not covered (a few ms); does
        nothing for flat and heightmap floors.

        Args:
            north_east: (K, 2) horizontal NED positions, m.
            reach: horizontal distance around them to cover, m: enough for a beam of
                ``max_range`` at angle ``a`` from vertical is ``max_range * sin(a)``.

        Raises:
            ValueError: the points and their reach do not fit in one window.
        """
        if self.kind != "procedural":
            return
        pts = np.asarray(north_east, dtype=float).reshape(-1, 2)
        if pts.size == 0:
            return
        finite, n_min, e_min, n_max, e_max = _extent(pts)
        if not (math.isfinite(reach) and reach >= 0) or not finite:
            raise ValueError(f"follow: expected finite positions and a reach >= 0 m, got "
                             f"reach {reach!r} and {np.count_nonzero(~np.isfinite(pts))} "
                             "non-finite coordinates")
        # In Python floats, the same operations as on numpy arrays: called every step.
        lo_n, lo_e, hi_n, hi_e = n_min - reach, e_min - reach, n_max + reach, e_max + reach
        centre_n, centre_e = self._centre[0] * self.cell, self._centre[1] * self.cell
        # Keep a cell clear of the edge, where hits count as side-wall hits.
        inner = (self._m - 1) * self.cell
        if (lo_n >= centre_n - inner and lo_e >= centre_e - inner
                and hi_n <= centre_n + inner and hi_e <= centre_e + inner):
            return
        lo, hi = np.array([lo_n, lo_e]), np.array([hi_n, hi_e])
        if np.any(hi - lo > 2 * inner - self.cell):
            raise ValueError(
                f"follow: the positions and their {reach:g} m reach span "
                f"{(hi - lo).max():.0f} m, more than the {2 * inner:.0f} m terrain window: "
                "expected fewer positions per call or a smaller reach")
        ci, cj = np.rint((lo + hi) / 2 / self.cell).astype(int)
        self._fill_window(int(ci), int(cj))

    # -- queries ------------------------------------------------------------------------

    def depth_at(self, north: np.ndarray, east: np.ndarray) -> np.ndarray:
        """Depth of the ray-cast surface below NED horizontal positions.

        Args:
            north, east: NED positions, m, any broadcastable shapes.

        Returns:
            Depth, m, positive down, of the broadcast shape; NaN outside the terrain that
            MuJoCo currently holds (the heightmap, or the procedural window).
        """
        if self.kind == "flat":
            finite = np.isfinite(np.asarray(north, dtype=float)) & np.isfinite(
                np.asarray(east, dtype=float))
            return np.where(finite, self.config.depth, np.nan)
        x, y = np.broadcast_arrays(np.asarray(north, dtype=float),
                                   -np.asarray(east, dtype=float))
        depth = _depths(np.ascontiguousarray(x).reshape(-1),
                        np.ascontiguousarray(y).reshape(-1), *self._grid())
        return depth.reshape(x.shape)

    def altitude(self, position_ned: np.ndarray) -> np.ndarray:
        """(K,) height above the ray-cast surface of (K, 3) float64 NED positions, m:
        ``depth_at`` minus the depth, NaN outside the terrain MuJoCo holds (one compiled
        pass on a flat floor: the environment asks twice a step)."""
        if self.kind == "flat":
            return _flat_altitude(position_ned, float(self.config.depth))
        return self.depth_at(position_ned[:, 0], position_ned[:, 1]) - position_ned[:, 2]

    def normal_at(self, north: np.ndarray, east: np.ndarray) -> np.ndarray:
        """Unit normal of the ray-cast surface below NED horizontal positions, pointing up
        into the water: the normal of the triangle ``depth_at`` interpolates on.

        Args:
            north, east: NED positions, m, any broadcastable shapes S.

        Returns:
            (*S, 3) NED unit normals; NaN outside the terrain MuJoCo currently holds.
        """
        x, y = np.broadcast_arrays(np.asarray(north, dtype=float),
                                   -np.asarray(east, dtype=float))
        if self.kind == "flat":
            up = np.where((np.isfinite(x) & np.isfinite(y))[..., None], 1.0, np.nan)
            return up * np.array([0.0, 0.0, -1.0])
        inside, d_north, d_east = _slopes(np.ascontiguousarray(x).reshape(-1),
                                          np.ascontiguousarray(y).reshape(-1), *self._grid())
        inside, d_north, d_east = (v.reshape(x.shape) for v in (inside, d_north, d_east))
        # The surface z = depth(n, e): its upward normal is (d_n, d_e, -1), normalised.
        normal = np.stack([d_north, d_east, -np.ones_like(d_north)], axis=-1)
        normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
        return np.where(inside[..., None], normal, np.nan)

    def _grid(self) -> tuple:
        """The terrain as ``_locate`` takes it: cover, origin, tile and cell counts, tile
        positions and half sizes, the heights (flat, float32) and the elevation ranges."""
        (rows, cols), (n_a, n_b), (hx, hy) = self._tile_cells, self._tiles, self._half
        return (*self._cover, *self._origin, rows, cols, n_a, n_b, self.cell,
                self._tile_pos, hx, hy, self._heights.reshape(-1), self._elevation)

    def cast(self, model: mujoco.MjModel, data: mujoco.MjData, origins_ned: np.ndarray,
             directions_ned: np.ndarray, *, max_range: float, exclude_body: int) -> np.ndarray:
        """Slant range of each beam to the seafloor, ray-cast by MuJoCo.

        Only geoms of group ``GROUP`` are seen, and none of body ``exclude_body``.

        Args:
            model, data: the compiled scene, with the vehicle posed (mj_forward done).
            origins_ned: (K, 3) beam origins, NED, m.
            directions_ned: (K, B, 3) unit beam directions, NED.
            max_range: longest range reported, m.
            exclude_body: id of a body the beams pass through (the vehicle); -1 for none.

        Returns:
            (K, B) slant ranges, m; NaN where there is no seafloor within ``max_range``.
        """
        origins = np.asarray(origins_ned, dtype=float) * _FLIP
        directions = np.asarray(directions_ned, dtype=float) * _FLIP
        if directions.ndim != 3 or origins.shape != (len(directions), 3) \
                or directions.shape[2] != 3:
            raise ValueError(f"cast: expected origins (K, 3) and directions (K, B, 3), got "
                             f"{origins.shape} and {directions.shape}")
        k_points, beams = directions.shape[:2]
        vectors = directions.reshape(k_points, 3 * beams)
        dist = np.empty((k_points, beams))
        geom = np.empty((k_points, beams), dtype=np.int32)
        for k in range(k_points):
            mujoco.mj_multiRay(model, data, origins[k], vectors[k], _GROUPS, 1, exclude_body,
                               geom[k], dist[k], None, beams, max_range)
        _drop_misses(dist, max_range)
        if self.kind != "flat":
            # MuJoCo's hfields are solids: a beam can hit the side walls or the base of
            # the terrain's edge tiles, or the padding of a heightmap, none of it seafloor.
            _drop_off_terrain(dist, geom, origins, directions, self._geoms, *self._cover)
        return dist


# The surface queries, compiled: the environment asks for a few points a step, where
# numpy's per-call overhead would dominate. Elementwise arithmetic in the order of the
# numpy expressions they replaced (no fastmath), so the same bits.

@numba.njit(cache=True)
def _locate(x, y, x_lo, x_hi, y_lo, y_hi, x0, y0, rows, cols, n_a, n_b, cell, tile_pos, hx,
            hy, heights, elevation):
    """Where MuJoCo's x, y (north, west) fall on the terrain: inside (bool), the tile's
    elevation range and its base's z, the fractional position (fu, fv) in the cell, and
    the three vertex heights of its triangle (h00, the side vertex, h11); outside the
    terrain, those of its (x_lo, y_lo) corner."""
    inside = (x >= x_lo) and (x <= x_hi) and (y >= y_lo) and (y <= y_hi)
    if not inside:
        x, y = x_lo, y_lo
    a = min(max(int((y - y0) // (rows * cell)), 0), n_a - 1)
    b = min(max(int((x - x0) // (cols * cell)), 0), n_b - 1)
    # From here on the same arithmetic as MuJoCo's mj_rayHfield, in the tile's frame.
    u = (x - tile_pos[a, b, 0] + hx) / (2.0 * hx / cols)  # fractional column
    v = (y - tile_pos[a, b, 1] + hy) / (2.0 * hy / rows)  # fractional row
    c = int(min(max(math.floor(u), 0.0), cols - 1))
    r = int(min(max(math.floor(v), 0.0), rows - 1))
    fu, fv = u - c, v - r
    k = ((a * n_b + b) * (rows + 1) + r) * (cols + 1) + c
    # float64 before any arithmetic, as numpy's astype(float) (numba's float() keeps float32).
    h00, h11 = np.float64(heights[k]), np.float64(heights[k + cols + 2])
    # Two triangles per cell, split along the (r, c) - (r + 1, c + 1) diagonal.
    if fu >= fv:  # the triangle with vertex (r, c + 1)
        side = np.float64(heights[k + 1])
    else:
        side = np.float64(heights[k + cols + 1])
    return inside, elevation[a, b], tile_pos[a, b, 2], fu, fv, h00, side, h11


@numba.njit(cache=True)
def _flat_altitude(position_ned, depth):
    """(K,) ``depth`` (NaN where north or east is not finite) minus the depth of (K, 3)
    NED positions: ``Seafloor.depth_at``'s flat floor, then the subtraction."""
    out = np.empty(position_ned.shape[0])
    for i in range(position_ned.shape[0]):
        finite = math.isfinite(position_ned[i, 0]) and math.isfinite(position_ned[i, 1])
        out[i] = (depth if finite else np.nan) - position_ned[i, 2]
    return out


@numba.njit(cache=True)
def _drop_misses(dist, max_range):
    """Set to NaN, in place, the (K, B) ranges of MuJoCo's ray casts that missed (-1) or
    hit beyond ``max_range``."""
    for k in range(dist.shape[0]):
        for j in range(dist.shape[1]):
            if dist[k, j] < 0 or dist[k, j] > max_range:
                dist[k, j] = np.nan


@numba.njit(cache=True)
def _extent(points):
    """Whether (K, 2) points (K > 0) are all finite, and their smallest and largest first
    and second coordinates (meaningless unless finite)."""
    lo0, lo1, hi0, hi1 = points[0, 0], points[0, 1], points[0, 0], points[0, 1]
    finite = True
    for i in range(len(points)):
        p0, p1 = points[i, 0], points[i, 1]
        finite = finite and math.isfinite(p0) and math.isfinite(p1)
        lo0, lo1, hi0, hi1 = min(lo0, p0), min(lo1, p1), max(hi0, p0), max(hi1, p1)
    return finite, lo0, lo1, hi0, hi1


@numba.njit(cache=True)
def _drop_off_terrain(dist, geom, origins, directions, geoms, x_lo, x_hi, y_lo, y_hi):
    """Set to NaN, in place, the (K, B) ranges ``dist`` whose hit on one of the hfield
    ``geoms`` (their ids, ``geom`` (K, B)) lies within ``EDGE`` of the terrain's edge or
    beyond (side walls, base, padding), from MuJoCo origins (K, 3) and directions
    (K, B, 3)."""
    for k in range(dist.shape[0]):
        for j in range(dist.shape[1]):
            if geom[k, j] not in geoms:
                continue
            x = origins[k, 0] + dist[k, j] * directions[k, j, 0]
            y = origins[k, 1] + dist[k, j] * directions[k, j, 1]
            if not (x > x_lo + EDGE and x < x_hi - EDGE and y > y_lo + EDGE
                    and y < y_hi - EDGE):
                dist[k, j] = np.nan


@numba.njit(cache=True)
def _depths(x, y, x_lo, x_hi, y_lo, y_hi, x0, y0, rows, cols, n_a, n_b, cell, tile_pos, hx,
            hy, heights, elevation):
    """(K,) depths, m, of the surface below (K,) MuJoCo x, y; NaN outside the terrain."""
    out = np.empty(len(x))
    for i in range(len(x)):
        inside, elev, z, fu, fv, h00, side, h11 = _locate(
            x[i], y[i], x_lo, x_hi, y_lo, y_hi, x0, y0, rows, cols, n_a, n_b, cell, tile_pos,
            hx, hy, heights, elevation)
        if fu >= fv:  # the triangle with vertex (r, c + 1)
            big, small = fu, fv
        else:
            big, small = fv, fu
        height = h00 + (side - h00) * big + (h11 - side) * small
        out[i] = -(z + height * elev) if inside else np.nan
    return out


@numba.njit(cache=True)
def _slopes(x, y, x_lo, x_hi, y_lo, y_hi, x0, y0, rows, cols, n_a, n_b, cell, tile_pos, hx,
            hy, heights, elevation):
    """(K,) inside, and the surface's d depth / d north and d depth / d east below (K,)
    MuJoCo x, y (those of the terrain's corner outside it)."""
    inside = np.empty(len(x), dtype=np.bool_)
    d_north, d_east = np.empty(len(x)), np.empty(len(x))
    for i in range(len(x)):
        inside[i], elev, z, fu, fv, h00, side, h11 = _locate(
            x[i], y[i], x_lo, x_hi, y_lo, y_hi, x0, y0, rows, cols, n_a, n_b, cell, tile_pos,
            hx, hy, heights, elevation)
        # The triangle's height gradient along the fractional column u and row v (linear
        # in each triangle), then in metres: u grows northward, v westward.
        if fu >= fv:
            dh_du, dh_dv = side - h00, h11 - side
        else:
            dh_du, dh_dv = h11 - side, side - h00
        d_north[i] = -elev * dh_du * cols / (2.0 * hx)
        d_east[i] = elev * dh_dv * rows / (2.0 * hy)  # (v runs west)
    return inside, d_north, d_east


def _tile_view(grid: np.ndarray, tile_cells: tuple[int, int]) -> np.ndarray:
    """(n_a, n_b, rows + 1, cols + 1) view of a grid as tiles sharing their edge vertices."""
    rows, cols = tile_cells
    return sliding_window_view(grid, (rows + 1, cols + 1))[::rows, ::cols]


def _copy_wrapped(tile: np.ndarray, row: int, col: int, *, out: np.ndarray) -> None:
    """``out[k, l] = tile[(row + k) mod R, (col + l) mod C]``, by block copies."""
    n_rows, n_cols = tile.shape
    i = 0
    while i < out.shape[0]:
        r = (row + i) % n_rows
        di = min(n_rows - r, out.shape[0] - i)
        j = 0
        while j < out.shape[1]:
            c = (col + j) % n_cols
            dj = min(n_cols - c, out.shape[1] - j)
            out[i:i + di, j:j + dj] = tile[r:r + di, c:c + dj]
            j += dj
        i += di


def _noise_tile(size: int, correlation_cells: float, rng: np.random.Generator) -> np.ndarray:
    """A periodic (size, size) Gaussian random field, zero mean and unit std over the tile,
    with correlation ``exp(-r^2 / correlation_cells^2)`` (r in cells)."""
    white = rng.standard_normal((size, size))
    k_row = 2 * np.pi * np.fft.fftfreq(size)[:, None]  # rad per cell
    k_col = 2 * np.pi * np.fft.rfftfreq(size)[None, :]
    # That correlation's spectrum is proportional to exp(-k^2 l^2 / 4): filter with its
    # square root.
    gain = np.exp(-(k_row**2 + k_col**2) * correlation_cells**2 / 8)
    field = np.fft.irfft2(np.fft.rfft2(white) * gain, s=(size, size))
    field -= field.mean()
    return field / field.std()


def _fast_size(n: int) -> int:
    """The smallest 2^a 3^b 5^c >= n: a size the FFT handles quickly."""
    best = 1 << max(n - 1, 0).bit_length()
    p5 = 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            p = p35
            while p < n:
                p *= 2
            best = min(best, p)
            p35 *= 3
        p5 *= 5
    return best


def _load_heightmap(path: str | None) -> np.ndarray:
    """Read and check a heightmap: (rows north, cols east) finite depths, m.

    The file is memory-mapped, so its shape and dtype are checked before any of its data
    is read (a header may claim terabytes)."""
    name = f"seafloor.heightmap {path!r}"
    expected = "a .npy file holding a 2-D (rows north, columns east) array of finite depths"
    if path is None or not Path(path).is_file():
        raise ConfigError(f"{name}: expected {expected}, found no such file")
    try:
        depths = np.load(path, mmap_mode="r", allow_pickle=False)
    except (OSError, ValueError, EOFError) as err:
        reason = " ".join(str(err).split()) or "empty"
        raise ConfigError(f"{name}: expected {expected}, found a file numpy cannot read "
                          f"({reason})") from None
    if not isinstance(depths, np.ndarray):
        depths.close()
        raise ConfigError(f"{name}: expected {expected}, found a .npz archive")
    if depths.ndim != 2 or min(depths.shape) < 2:
        raise ConfigError(f"{name}: expected {expected} of at least 2 x 2, found shape "
                          f"{depths.shape}")
    if depths.size > MAX_HEIGHTMAP_VERTICES:
        raise ConfigError(f"{name}: expected {expected} of at most {MAX_HEIGHTMAP_VERTICES} "
                          f"depths (4096 x 4096), found shape {depths.shape}")
    if depths.dtype.kind not in "iuf":
        raise ConfigError(f"{name}: expected {expected}, found dtype {depths.dtype}")
    depths = np.array(depths, dtype=float)
    bad = np.count_nonzero(~np.isfinite(depths))
    if bad:
        raise ConfigError(f"{name}: expected {expected}, found {bad} non-finite value(s)")
    deepest = float(np.abs(depths).max())
    if deepest > MAX_DEPTH:
        raise ConfigError(f"{name}: expected {expected} within +/-{MAX_DEPTH:g} m (the "
                          f"deepest ocean), found {deepest:g} m")
    return depths
