"""Fossen-style 6-DOF hydrodynamics of a torpedo hull, in body axes (FRD) at the centre of
buoyancy (CO, the body origin).

The equation of motion, with nu = [u, v, w, p, q, r] and nu_r = nu - [R^T v_current; 0]::

    (M_RB + M_A) nu_dot = tau_water + tau_weight - C_RB(nu) nu
    tau_water = tau_propeller + tau_fins + tau_hull + tau_buoyancy
                - C_A(nu_r) nu_r - D nu_r - M_A [omega x v_current_body; 0]

MuJoCo integrates the rigid body and applies the weight itself, so it receives
``tau_water - M_A nu_dot``: the added-mass reaction is computed from this step's own
acceleration, solved with the full mass matrix, never lagged by a step. MuJoCo's rigid-body
solve then reproduces ``nu_dot`` exactly (see ``water_wrench``).

Every coefficient is derived here from the model file: the hull's size from geom
``hull``, mass and inertia from the body, the rest from the ``<custom>`` numerics
(models/README.md gives the derivation and the sources).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import mujoco
import numba
import numpy as np

from auvsim.errors import ConfigError
from auvsim.physics.frames import FLIP, skew

# The model's actuators, in the order of the actuator commands (shaft rpm, rudder and
# stern-plane angles): MuJoCo applies no force of theirs (their gain is 0), they carry the
# control ranges.
ACTUATORS = ("propeller", "rudder", "stern_planes")
N_STRIPS = 20  # cross-flow drag strips along the hull (Fossen uses 20 as well)
# Hull length over diameter (a / b) where Lamb's factors are computed accurately: at
# 1 + 1e-7 k' comes out negative, at 1e9 the eccentricity rounds to 1. The A18-D has 11,
# the REMUS 100 8.4.
MIN_SLENDERNESS, MAX_SLENDERNESS = 1.001, 1e4
# The physics step: the shipped models take 10 ms. At 100 ms the REMUS 100 blows up in a
# hard turn at speed (measured: MuJoCo's QACC warning), at 50 ms it does not; 20 ms keeps
# a margin. Below 1 ms a mission costs ten times the steps of the shipped models.
MIN_TIMESTEP, MAX_TIMESTEP = 1e-3, 0.02  # s
MAX_GRAVITY = 30.0  # m/s^2: any planet's or moon's surface (Jupiter's is 24.8)
MASS_FACTOR = 2.0  # how far the mass may be from the hull's displaced mass, either way
INERTIA_FACTOR = 10.0  # how far the moments may be from the solid spheroid's, either way


class Hydro(NamedTuple):
    """All coefficients of the force model, in SI units and FRD body axes at the CO.

    A NamedTuple so that the compiled step functions take it as one argument.
    """

    gravity: float  # m/s^2
    mass: float  # kg
    weight: float  # N
    buoyancy: float  # N (displacement plus the configured net buoyancy)
    r_g: np.ndarray  # (3,) m, centre of gravity
    r_b: np.ndarray  # (3,) m, centre of buoyancy
    inertia_o: np.ndarray  # (3, 3) kg m^2, rigid-body inertia about the CO
    added_mass: np.ndarray  # (6,) diagonal of M_A (kg, kg m^2)
    mass_matrix_inv: np.ndarray  # (6, 6) inverse of M_RB + M_A
    linear_damping: np.ndarray  # (6,) diagonal of D before the speed fade
    munk_factor: float  # 1 keeps the Munk moment of C_A, 0 zeroes it as Fossen's REMUS does
    axial_drag: float  # N s^2/m^2: X = -axial_drag |u_r| u_r
    strip_x: np.ndarray  # (N_STRIPS,) m, strip centres along x
    strip_drag: np.ndarray  # (N_STRIPS,) N s^2/m^2 per strip: 1/2 rho Cd d(x) dx
    hull_lift: float  # N s^2/m^2: Y = -hull_lift u_r v_r
    hull_lift_x: float  # m, where the hull lift acts
    fin_x: float  # m, x of the rudder and stern-plane pairs
    fin_lift: float  # N s^2/m^2 per rad, for a PAIR of fins: 1/2 rho (2 S) CL_alpha
    fin_stall: float  # rad
    fin_flow_axes: bool  # lift and drag in the fins' flow axes; False: body axes (v3 files)
    rudder_max: float  # rad, the rudder's angle limit
    planes_max: float  # rad, the stern planes' angle limit
    fin_tau: float  # s, servo time constant
    fin_rate: float  # rad/s, rate limit
    prop_d: float  # m
    prop_kt: np.ndarray  # (2,) KT0 and the slope (KT_max - KT0) / Ja_max
    prop_kq: np.ndarray  # (2,) KQ0 and the slope (KQ_max - KQ0) / Ja_max
    prop_rotation: float  # +1: the shaft reaction rolls the hull to starboard (K = +Q)
    rho: float  # kg/m^3
    thrust_deduction: float
    wake_fraction: float
    shaft_tau: float  # s
    rpm_max: float


def lamb_k_factors(a: float, b: float) -> tuple[float, float, float]:
    """Lamb's added-mass factors of a prolate spheroid with semi-axes a > b.

    Returns (k1, k2, k_prime): axial, transverse and rotational factors, so that
    X_udot = -k1 m, Y_vdot = Z_wdot = -k2 m and M_qdot = N_rdot = -k_prime I_y for the
    displaced mass m and its moment of inertia I_y (Lamb 1932, in Fossen 2021, sec. 8.4).

    Raises:
        ConfigError: unless ``MIN_SLENDERNESS <= a / b <= MAX_SLENDERNESS``, where the
            formulas keep their accuracy (nearer a sphere they cancel to noise, and a needle
            rounds the eccentricity to 1).
    """
    if not (b > 0 and MIN_SLENDERNESS <= a / b <= MAX_SLENDERNESS):
        raise ConfigError(f"lamb_k_factors: expected semi-axes a > b > 0 with a / b in "
                          f"[{MIN_SLENDERNESS:g}, {MAX_SLENDERNESS:g}], got a = {a!r}, "
                          f"b = {b!r}")
    e = math.sqrt(1.0 - (b / a) ** 2)
    log_term = math.log((1.0 + e) / (1.0 - e))
    alpha0 = 2.0 * (1.0 - e**2) / e**3 * (0.5 * log_term - e)
    beta0 = 1.0 / e**2 - (1.0 - e**2) / (2.0 * e**3) * log_term
    k1 = alpha0 / (2.0 - alpha0)
    k2 = beta0 / (2.0 - beta0)
    d = beta0 - alpha0
    k_prime = e**4 * d / ((2.0 - e**2) * (2.0 * e**2 - (2.0 - e**2) * d))
    return k1, k2, k_prime


def _numeric(model: mujoco.MjModel, name: str) -> np.ndarray:
    try:
        return np.array(model.numeric(name).data, dtype=float)
    except KeyError:
        if name in _V3_DEFAULTS:
            return np.array([_V3_DEFAULTS[name]])
        raise KeyError(f"model has no <numeric name={name!r}>") from None


# Every <numeric> the force model reads: how many values, and the range of each
# (lo, hi, whether lo itself is allowed).
_NUMERICS = {
    "water_density": (1, (0.0, math.inf, False)),
    "axial_drag_coefficient": (1, (0.0, math.inf, True)),
    "crossflow_drag_coefficient": (1, (0.0, math.inf, True)),
    "hull_lift_coefficient": (1, (0.0, math.inf, True)),
    "hull_lift_center": (1, (-math.inf, math.inf, True)),  # within the hull: load_hydro
    "roll_added_inertia_ratio": (1, (0.0, math.inf, True)),
    "linear_damping_time_constants": (3, (0.0, math.inf, True)),
    "roll_damping_ratio": (1, (0.0, math.inf, True)),
    "pitch_damping_ratio": (1, (0.0, math.inf, True)),
    "yaw_damping_time_constant": (1, (0.0, math.inf, True)),
    "munk_moment_factor": (1, (0.0, 1.0, True)),
    "fin_area": (1, (0.0, math.inf, True)),
    "fin_lift_slope": (1, (0.0, math.inf, True)),
    "fin_stall_angle": (1, (0.0, math.pi / 2, False)),
    "fin_time_constant": (1, (0.0, math.inf, False)),
    "fin_rate_limit": (1, (0.0, math.inf, False)),
    "propeller_diameter": (1, (0.0, math.inf, False)),
    # KT0 and Ja_max divide the feedforward and the slopes; KQ0, KT_max, KQ_max any sign.
    "propeller_coefficients": (5, (-math.inf, math.inf, True)),
    "thrust_deduction": (1, (0.0, 1.0, True)),
    "wake_fraction": (1, (0.0, 1.0, True)),
    "shaft_time_constant": (1, (0.0, math.inf, False)),
    # +1 or -1 (checked in _check_model): which way the shaft reaction rolls the hull.
    "propeller_rotation": (1, (-1.0, 1.0, True)),
}
# Numerics that models of the layout before issue 10 (tests/data/models-v3) lack, and the
# value that gives those models exactly the behaviour they had: their shaft reaction rolled
# the hull to port.
_V3_DEFAULTS = {"propeller_rotation": -1.0}


def _v3_layout(model: mujoco.MjModel) -> bool:
    """A model of the layout before issue 10 (it lacks every numeric of ``_V3_DEFAULTS``):
    its fins' forces stay in body axes, as that revision computed them."""
    names = {model.numeric(i).name for i in range(model.nnumeric)}
    return not names & _V3_DEFAULTS.keys()


def _require(ok: bool, what: str, expected: str, got: object) -> None:
    if not ok:
        raise ConfigError(f"{what}: expected {expected}, got {got}")


def _finite_array(values) -> bool:
    return bool(np.all(np.isfinite(np.asarray(values, dtype=float))))


def control_ranges(model: mujoco.MjModel) -> dict[str, np.ndarray]:
    """Each of the vehicle's actuators' control range (2,), by name (``ACTUATORS``).

    Raises:
        KeyError: an actuator is missing.
    """
    return {name: np.array(model.actuator(name).ctrlrange) for name in ACTUATORS}


def _check_model(model: mujoco.MjModel, ranges: dict[str, np.ndarray]) -> None:
    """Refuse a vehicle model the force model cannot use: the named elements missing, or
    a mass, inertia, hull, coefficient, control range (``ranges``) or physics option that
    is not finite or not in its physical range.

    Raises:
        ConfigError: naming the quantity (the caller names the file).
        KeyError: a named element is missing.
    """
    body = model.body("vehicle").id
    joint = int(model.body_jntadr[body])
    _require(joint >= 0 and model.jnt_type[joint] == mujoco.mjtJoint.mjJNT_FREE
             and model.jnt_qposadr[joint] == 0 and model.jnt_dofadr[joint] == 0,
             "body 'vehicle'", "a free joint, the model's first", "none" if joint < 0 else
             f"joint {model.joint(joint).name!r} of type {int(model.jnt_type[joint])}")
    hull = model.geom("hull").id
    size = np.array(model.geom_size[hull])
    _require(model.geom_type[hull] == mujoco.mjtGeom.mjGEOM_ELLIPSOID, "geom 'hull'",
             "an ellipsoid", f"geom type {int(model.geom_type[hull])}")
    a, b = float(size[0]), float(size[1])
    _require(_finite_array(size) and b > 0 and MIN_SLENDERNESS <= a / b <= MAX_SLENDERNESS,
             "geom 'hull' size", f"semi-axes a > b > 0 m of a hull longer than wide, "
             f"{MIN_SLENDERNESS:g} <= a / b <= {MAX_SLENDERNESS:g}", size.tolist())
    # The force model's buoyancy is the hull's displacement, so the vehicle's mass must be
    # near the displaced mass (the shipped models' equals it); far from it the vehicle
    # sinks or rises like a stone, and a tiny mass or inertia leaves MuJoCo's acceleration
    # to round-off.
    rho = float(_numeric(model, "water_density")[0])
    displaced = rho * 4.0 / 3.0 * math.pi * a * b * b
    m = float(model.body_mass[body])
    _require(math.isfinite(m) and displaced / MASS_FACTOR <= m <= displaced * MASS_FACTOR,
             "body 'vehicle' mass", f"a mass within a factor {MASS_FACTOR:g} of the hull's "
             f"displaced {displaced:.4g} kg (a vehicle near neutral buoyancy)", m)
    inertia = np.array(model.body_inertia[body])
    spheroid = m * np.array([2.0 / 5.0 * b * b, (a * a + b * b) / 5.0, (a * a + b * b) / 5.0])
    _require(_finite_array(inertia) and bool(np.all(inertia >= spheroid / INERTIA_FACTOR))
             and bool(np.all(inertia <= spheroid * INERTIA_FACTOR)), "body 'vehicle' inertia",
             f"principal moments within a factor {INERTIA_FACTOR:g} of the solid spheroid's "
             f"{np.round(spheroid, 6).tolist()} kg m^2", inertia.tolist())
    iquat = np.array(model.body_iquat[body])
    _require(np.allclose(np.abs(iquat), [1.0, 0.0, 0.0, 0.0], atol=1e-9),
             "body 'vehicle' inertia", "principal axes along the body's (diaginertia)",
             f"axes rotated by the quaternion {iquat.tolist()}")
    cg = np.array(model.body_ipos[body])
    _require(_finite_array(cg) and bool(np.all(np.abs(cg) <= [a, b, b])),
             "body 'vehicle' centre of gravity", "a point within the hull's box "
             f"(+/-{a:g}, +/-{b:g}, +/-{b:g}) m", cg.tolist())
    for name, (count, (lo, hi, closed)) in _NUMERICS.items():
        data = _numeric(model, name)
        _require(data.size == count and _finite_array(data)
                 and bool(np.all((data >= lo) if closed else (data > lo)))
                 and bool(np.all(data <= hi)), f"<numeric name={name!r}>",
                 f"{count} finite value(s) in {'[' if closed else '('}{lo:g}, {hi:g}]",
                 data.tolist())
    kt0, _, _, _, ja_max = _numeric(model, "propeller_coefficients")
    _require(kt0 > 0 and ja_max > 0, "<numeric name='propeller_coefficients'>",
             "KT0 > 0 and Ja_max > 0", [float(kt0), float(ja_max)])
    rotation = float(_numeric(model, "propeller_rotation")[0])
    _require(rotation in (-1.0, 1.0), "<numeric name='propeller_rotation'>",
             "+1 (the shaft reaction rolls the hull to starboard) or -1 (to port)", rotation)
    _require(abs(float(_numeric(model, "hull_lift_center")[0])) <= a,
             "<numeric name='hull_lift_center'>", f"a point within the hull, +/-{a:g} m",
             float(_numeric(model, "hull_lift_center")[0]))
    for site in ("imu", "dvl", "rudder"):
        pos = np.array(model.site(site).pos)
        _require(_finite_array(pos) and bool(np.all(np.abs(pos) <= [a, 2 * b, 2 * b])),
                 f"site {site!r} position", f"a point on the hull, within (+/-{a:g}, "
                 f"+/-{2 * b:g}, +/-{2 * b:g}) m", pos.tolist())
    for name, most in zip(ACTUATORS, (math.inf, math.pi / 2, math.pi / 2), strict=True):
        limit = ranges[name]
        # The force model takes the upper limit as the limit either way.
        _require(_finite_array(limit) and 0 < limit[1] <= most, f"actuator {name!r} ctrlrange",
                 f"a finite range whose upper limit is in (0, {most:g}]", limit.tolist())
    dt = float(model.opt.timestep)
    _require(MIN_TIMESTEP <= dt <= MAX_TIMESTEP, "option timestep",
             f"a physics step in [{MIN_TIMESTEP:g}, {MAX_TIMESTEP:g}] s", dt)
    gravity = np.array(model.opt.gravity)
    _require(_finite_array(gravity) and gravity[0] == 0 and gravity[1] == 0
             and 0 < -gravity[2] <= MAX_GRAVITY, "option gravity",
             f"0 0 -g with 0 < g <= {MAX_GRAVITY:g} m/s^2", gravity.tolist())


def load_hydro(model: mujoco.MjModel, *, net_buoyancy: float = 0.0,
               ranges: dict[str, np.ndarray] | None = None) -> Hydro:
    """Derive the force model's coefficients from a vehicle model.

    Args:
        model: a compiled vehicle model (models/auv.xml or one of the same layout).
        net_buoyancy: buoyancy minus weight, N (positive: the vehicle floats up).
        ranges: the actuators' control ranges (``control_ranges``) of a model compiled
            without its actuators (``auvsim.physics.vehicle.Vehicle``); None: the model's own.

    Raises:
        ConfigError, KeyError: the model is not one the force model can use
            (``_check_model``).
    """
    ranges = control_ranges(model) if ranges is None else ranges
    _check_model(model, ranges)
    num = lambda name: float(_numeric(model, name)[0])  # noqa: E731
    rho = num("water_density")
    g = -float(model.opt.gravity[2])
    body = model.body("vehicle").id
    hull = model.geom("hull")
    a, b = float(hull.size[0]), float(hull.size[1])
    volume = 4.0 / 3.0 * math.pi * a * b * b

    m = float(model.body_mass[body])
    r_g = np.array(model.body_ipos[body]) * FLIP
    inertia_g = np.diag(model.body_inertia[body])
    inertia_o = inertia_g - m * skew(r_g) @ skew(r_g)
    m_rb = np.zeros((6, 6))
    m_rb[:3, :3] = m * np.eye(3)
    m_rb[:3, 3:] = -m * skew(r_g)
    m_rb[3:, :3] = m * skew(r_g)
    m_rb[3:, 3:] = inertia_o

    # Added mass of the displaced spheroid (its own m and I_y, not the body's).
    k1, k2, k_prime = lamb_k_factors(a, b)
    m_disp = rho * volume
    iy_disp = m_disp * (a * a + b * b) / 5.0
    added = np.array(
        [k1 * m_disp, k2 * m_disp, k2 * m_disp, num("roll_added_inertia_ratio") * inertia_g[0, 0],
         k_prime * iy_disp, k_prime * iy_disp]
    )
    total = m_rb + np.diag(added)

    # Linear damping from time constants and damping ratios (Fossen's REMUS 100 method).
    weight = m * g
    bg = r_g[2]
    t_lin = _numeric(model, "linear_damping_time_constants")
    damping = np.zeros(6)
    for i in range(3):
        damping[i] = total[i, i] / t_lin[i] if t_lin[i] > 0 else 0.0
    if bg > 0:
        w_roll = math.sqrt(weight * bg / total[3, 3])
        w_pitch = math.sqrt(weight * bg / total[4, 4])
        damping[3] = 2.0 * num("roll_damping_ratio") * w_roll * total[3, 3]
        damping[4] = 2.0 * num("pitch_damping_ratio") * w_pitch * total[4, 4]
    t_yaw = num("yaw_damping_time_constant")
    damping[5] = total[5, 5] / t_yaw if t_yaw > 0 else 0.0

    edges = np.linspace(-a, a, N_STRIPS + 1)
    strip_x = 0.5 * (edges[1:] + edges[:-1])
    strip_d = 2.0 * b * np.sqrt(1.0 - (strip_x / a) ** 2)
    strip_drag = 0.5 * rho * num("crossflow_drag_coefficient") * strip_d * np.diff(edges)

    kt0, kq0, kt_max, kq_max, ja_max = _numeric(model, "propeller_coefficients")
    return Hydro(
        gravity=g,
        mass=m,
        weight=weight,
        buoyancy=rho * g * volume + net_buoyancy,
        r_g=r_g,
        r_b=np.zeros(3),
        inertia_o=inertia_o,
        added_mass=added,
        mass_matrix_inv=np.linalg.inv(total),
        linear_damping=damping,
        munk_factor=num("munk_moment_factor"),
        axial_drag=0.5 * rho * math.pi * b * b * num("axial_drag_coefficient"),
        strip_x=strip_x,
        strip_drag=strip_drag,
        hull_lift=0.5 * rho * (2.0 * b) ** 2 * num("hull_lift_coefficient"),
        hull_lift_x=num("hull_lift_center"),
        fin_x=float(model.site("rudder").pos[0]),
        fin_lift=0.5 * rho * 2.0 * num("fin_area") * num("fin_lift_slope"),
        fin_stall=num("fin_stall_angle"),
        fin_flow_axes=not _v3_layout(model),
        rudder_max=float(ranges["rudder"][1]),
        planes_max=float(ranges["stern_planes"][1]),
        fin_tau=num("fin_time_constant"),
        fin_rate=num("fin_rate_limit"),
        prop_d=num("propeller_diameter"),
        prop_kt=np.array([kt0, (kt_max - kt0) / ja_max]),
        prop_kq=np.array([kq0, (kq_max - kq0) / ja_max]),
        prop_rotation=num("propeller_rotation"),
        rho=rho,
        thrust_deduction=num("thrust_deduction"),
        wake_fraction=num("wake_fraction"),
        shaft_tau=num("shaft_time_constant"),
        rpm_max=float(ranges["propeller"][1]),
    )


# Small 3-vector helpers on tuples: they live on the stack, where numpy arrays would be
# heap allocations costing more than the arithmetic in this per-step code.
@numba.njit(cache=True, inline="always")
def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@numba.njit(cache=True, inline="always")
def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@numba.njit(cache=True, inline="always")
def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@numba.njit(cache=True, inline="always")
def mul(a, b):
    """Elementwise product (a diagonal matrix times a vector)."""
    return (a[0] * b[0], a[1] * b[1], a[2] * b[2])


@numba.njit(cache=True, inline="always")
def scale(k, a):
    return (k * a[0], k * a[1], k * a[2])


@numba.njit(cache=True, inline="always")
def mat3_vec(m, a):
    """m @ a for a (3, 3) array and a 3-tuple."""
    return (m[0, 0] * a[0] + m[0, 1] * a[1] + m[0, 2] * a[2],
            m[1, 0] * a[0] + m[1, 1] * a[1] + m[1, 2] * a[2],
            m[2, 0] * a[0] + m[2, 1] * a[1] + m[2, 2] * a[2])


@numba.njit(cache=True, inline="always")
def mat3t_vec(m, a):
    """m.T @ a for a (3, 3) array and a 3-tuple."""
    return (m[0, 0] * a[0] + m[1, 0] * a[1] + m[2, 0] * a[2],
            m[0, 1] * a[0] + m[1, 1] * a[1] + m[2, 1] * a[2],
            m[0, 2] * a[0] + m[1, 2] * a[1] + m[2, 2] * a[2])


@numba.njit(cache=True)
def mat_vec(a, x, out):
    """a @ x by loops, into ``out`` (numba's @ calls BLAS, whose overhead dwarfs a 6x6
    product), from zero in the order of j."""
    for i in range(a.shape[0]):
        out[i] = 0.0
        for j in range(x.shape[0]):
            out[i] += a[i, j] * x[j]
    return out


@numba.njit(cache=True)
def propeller(h, rpm, u_r):
    """Thrust (N, along +x) and shaft torque (N m) of the propeller at ``rpm`` and surge
    speed ``u_r``: T = rho n^2 D^4 KT(J), Q = rho n^2 D^5 KQ(J), J = Va / (n D),
    Va = (1 - w) u_r, with KT and KQ linear in J (Fossen's Wageningen B-series fit).

    The torque is the shaft power over the shaft speed, Q = T Va / (2 pi n eta_0(J)), with
    the open-water efficiency eta_0 = J KT / (2 pi KQ) of the same fit (0.6 to 0.7 at the
    shipped models' cruise; models/README.md checks it against the REMUS 100's battery).
    In reverse only KT0 and KQ0 act."""
    n = rpm / 60.0
    if n > 0.0:
        va_over_d = (1.0 - h.wake_fraction) * u_r / h.prop_d
        thrust = h.rho * h.prop_d**4 * (h.prop_kt[0] * n * n + h.prop_kt[1] * va_over_d * n)
        torque = h.rho * h.prop_d**5 * (h.prop_kq[0] * n * n + h.prop_kq[1] * va_over_d * n)
    else:
        thrust = h.rho * h.prop_d**4 * h.prop_kt[0] * abs(n) * n
        torque = h.rho * h.prop_d**5 * h.prop_kq[0] * abs(n) * n
    return thrust, torque


@numba.njit(cache=True)
def water_wrench(h, nu, rot, actuators, current_ned, disturbance=None):
    """Body acceleration and the wrench MuJoCo must apply for it.

    Args:
        h: the coefficients (``Hydro``).
        nu: (6,) body velocity [u, v, w, p, q, r], m/s and rad/s, FRD at the CO.
        rot: (3, 3) rotation body -> NED.
        actuators: (3,) propeller rpm, rudder and stern-plane angles (rad).
        current_ned: (3,) ocean current at the vehicle now, m/s, NED (its change over
            time is neglected: ``auvsim.physics.water``).
        disturbance: (6,) a turbulent force and moment about the CO, FRD (N, N m), added
            to the water's (``auvsim.physics.water``); None (the default) for none.

    Returns:
        nu_dot: (6,) body acceleration, d/dt of ``nu``'s components.
        applied: (6,) force and moment about the CO, FRD, that MuJoCo applies besides the
            weight: everything the water does, including the added-mass reaction
            -M_A nu_dot.
        thrust: propeller thrust, N.
    """
    nu_dot, applied = np.empty(6), np.empty(6)
    thrust = water_wrench_into(h, nu, rot, actuators, current_ned, disturbance, np.empty(6),
                               nu_dot, applied)
    return nu_dot, applied, thrust


@numba.njit(cache=True)
def water_wrench_into(h, nu, rot, actuators, current_ned, disturbance, tau, nu_dot, applied):
    """``water_wrench`` into the caller's (6,) arrays ``nu_dot`` and ``applied``, with
    ``tau`` (6,) for scratch; returns the thrust. The physics loop's: a step allocates
    nothing (NRT's allocations cost as much as the arithmetic)."""
    v = (nu[0], nu[1], nu[2])
    w = (nu[3], nu[4], nu[5])
    cur = (current_ned[0], current_ned[1], current_ned[2])
    v_c = mat3t_vec(rot, cur)
    vr = sub(v, v_c)
    a1 = (h.added_mass[0], h.added_mass[1], h.added_mass[2])
    a2 = (h.added_mass[3], h.added_mass[4], h.added_mass[5])
    r_g = (h.r_g[0], h.r_g[1], h.r_g[2])
    r_b = (h.r_b[0], h.r_b[1], h.r_b[2])
    for i in range(6):
        tau[i] = 0.0

    # Restoring: buoyancy here, the weight only in nu_dot (MuJoCo applies it itself).
    down = (rot[2, 0], rot[2, 1], rot[2, 2])  # NED z axis in body axes
    f_b = scale(-h.buoyancy, down)
    m_b = cross(r_b, f_b)

    # Added-mass Coriolis and centripetal terms, C_A(nu_r) nu_r, and the current term.
    a1v = mul(a1, vr)
    f_a = add(cross(w, a1v), mul(a1, cross(w, v_c)))
    m_a = add(scale(h.munk_factor, cross(vr, a1v)), cross(w, mul(a2, w)))
    for i in range(3):
        tau[i] = f_b[i] - f_a[i]
        tau[3 + i] = m_b[i] - m_a[i]

    # Linear damping, surge/sway/heave faded out with speed as in Fossen's REMUS model.
    speed = math.sqrt(vr[0] ** 2 + vr[1] ** 2 + vr[2] ** 2)
    fade = math.exp(-3.0 * speed)
    for i in range(3):
        tau[i] -= h.linear_damping[i] * fade * vr[i]
    for i in range(3):
        tau[3 + i] -= h.linear_damping[3 + i] * w[i]

    # Hull: axial drag, strip-theory cross-flow drag, and viscous body lift.
    tau[0] -= h.axial_drag * abs(vr[0]) * vr[0]
    for k in range(h.strip_x.shape[0]):
        x = h.strip_x[k]
        cy = vr[1] + x * w[2]
        cz = vr[2] - x * w[1]
        c = math.sqrt(cy * cy + cz * cz)
        fy = -h.strip_drag[k] * c * cy
        fz = -h.strip_drag[k] * c * cz
        tau[1] += fy
        tau[2] += fz
        tau[4] -= x * fz
        tau[5] += x * fy
    fy = -h.hull_lift * vr[0] * vr[1]
    fz = -h.hull_lift * vr[0] * vr[2]
    tau[1] += fy
    tau[2] += fz
    tau[4] -= h.hull_lift_x * fz
    tau[5] += h.hull_lift_x * fy

    # Fins: lift from the fin angle plus the local flow angle, induced drag, stall. Lift and
    # drag are, by their definitions, normal to and against the fin's velocity through the
    # water (uf, c) in the pair's plane: resolved into body axes through the flow angle
    # beta (cos beta = |uf| / U, sin beta = c / U). Models of the v3 layout keep the body
    # axes they had (lift along y or z, drag along -x: ``Hydro.fin_flow_axes``).
    uf = vr[0]
    vf = vr[1] + h.fin_x * w[2]
    wf = vr[2] - h.fin_x * w[1]
    for axis in range(2):  # 0: rudder pair (x-y plane), 1: stern-plane pair (x-z plane)
        cross_flow = vf if axis == 0 else wf
        u2 = uf * uf + cross_flow * cross_flow
        alpha = actuators[1 + axis] + math.atan2(cross_flow, abs(uf))
        alpha = min(max(alpha, -h.fin_stall), h.fin_stall)
        lift = -h.fin_lift * u2 * alpha
        drag = h.fin_lift * u2 * alpha * alpha
        if not h.fin_flow_axes:
            fx, fn = -drag, lift
        elif u2 > 0.0:
            speed_f = math.sqrt(u2)  # lift along (-sgn(uf) c, |uf|) / U, drag against (uf, c)
            fx = (-math.copysign(1.0, uf) * cross_flow * lift - uf * drag) / speed_f
            fn = (abs(uf) * lift - cross_flow * drag) / speed_f
        else:
            fx, fn = 0.0, 0.0
        tau[0] += fx
        if axis == 0:
            tau[1] += fn
            tau[5] += h.fin_x * fn
        else:
            tau[2] += fn
            tau[4] -= h.fin_x * fn

    # Propeller: thrust less the thrust deduction; the hull takes the shaft reaction, whose
    # sign is the propeller's hand (models/README.md).
    thrust, torque = propeller(h, actuators[0], vr[0])
    tau[0] += (1.0 - h.thrust_deduction) * thrust
    tau[3] += h.prop_rotation * torque

    # Motion disturbances (auvsim.physics.water): added only when given, so that without them
    # the arithmetic is exactly what it was.
    if disturbance is not None:
        for i in range(6):
            tau[i] += disturbance[i]

    # Rigid-body terms for the acceleration: weight and C_RB(nu) nu.
    f_w = scale(h.weight, down)
    wv = cross(w, v)
    f_rb = sub(f_w, scale(h.mass, add(wv, cross(w, cross(w, r_g)))))
    m_rb = sub(sub(cross(r_g, f_w), scale(h.mass, cross(r_g, wv))),
               cross(w, mat3_vec(h.inertia_o, w)))
    rhs = applied  # its scratch until the end
    for i in range(6):
        rhs[i] = tau[i]
    for i in range(3):
        rhs[i] += f_rb[i]
        rhs[3 + i] += m_rb[i]
    mat_vec(h.mass_matrix_inv, rhs, nu_dot)
    for i in range(6):
        applied[i] = tau[i] - h.added_mass[i] * nu_dot[i]
    return thrust
