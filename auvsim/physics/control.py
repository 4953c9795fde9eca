"""Autopilots for speed, heading and depth, and the actuator servo dynamics.

Gains are nondimensional: times scale with L/U (hull length over speed), so the same
gains serve vehicles of different size. Each channel is either closed loop (the reference
is a speed, heading or depth) or open loop (the reference is the actuator command itself).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba

from auvsim.physics.hydro import Hydro, propeller


class Gains(NamedTuple):
    """Autopilot gains; ``*_d`` multiply L/U, ``*_i`` multiply U/L."""

    length: float = 5.5  # m, hull length that sets the time scale
    speed_p: float = 1.0  # speed correction per speed error
    speed_i: float = 0.5  # speed correction per (integrated speed error x U/L)
    heading_p: float = 1.0  # rad of rudder per rad of heading error
    heading_i: float = 0.2
    heading_d: float = 1.2  # rad of rudder per (rad/s x L/U) of yaw rate
    pitch_max: float = math.radians(20.0)
    depth_p: float = 0.8  # rad of pitch per hull length of depth error
    depth_i: float = 0.02
    depth_d: float = 1.5  # rad of pitch per unit of (depth rate / speed)
    pitch_p: float = 1.5  # rad of stern planes per rad of pitch error
    pitch_d: float = 1.5
    # True: the speed channel sets the shaft to the rpm that holds its reference in
    # straight flight (``feedforward_rpm`` with ``linear_damping``) and leaves it there, as
    # a real AUV commands propeller rpm: the speed then drops in a turn as the hull's drag
    # grows. False (the default): a speed loop raises the rpm to hold the speed through the
    # water.
    hold_rpm: bool = False
    # True: a heading change larger than the PID's own braking point is flown at full
    # rudder (the rudder commanded past its limit, toward the new heading) until the
    # heading error falls to the angle at which the yaw-rate term equals the heading term,
    # |e| = heading_d (L/U) |r| / heading_p, and the PID takes over from there: a turn as
    # a survey AUV flies its line turns. False (the default): the PID throughout, whose
    # yaw-rate term backs the rudder off as the turn builds.
    full_rudder_turns: bool = False


@numba.njit(cache=True)
def feedforward_rpm(h: Hydro, speed: float, linear_damping: bool = False) -> float:
    """Shaft speed (rpm) at which thrust balances the quadratic hull drag at ``speed``.

    With ``linear_damping`` it balances the whole surge drag in straight level flight: the
    quadratic hull drag and the linear damping with its speed fade (``hydro``), the rpm a
    vehicle's speed table gives (the speed channel's with ``Gains.hold_rpm``).
    """
    k = (1.0 - h.thrust_deduction) * h.rho * h.prop_d**4
    a = k * h.prop_kt[0]
    b = k * h.prop_kt[1] * (1.0 - h.wake_fraction) * speed / h.prop_d
    c = h.axial_drag * speed * speed
    if linear_damping:
        c = c + h.linear_damping[0] * math.exp(-3.0 * speed) * speed
    n = (-b + math.sqrt(b * b + 4.0 * a * c)) / (2.0 * a)
    return 60.0 * n


def max_speed(h: Hydro) -> float:
    """Steady straight-line speed (m/s) at full shaft speed, from the same force balance."""
    lo, hi = 0.0, 20.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        thrust, _ = propeller(h, h.rpm_max, mid)
        if (1.0 - h.thrust_deduction) * thrust > h.axial_drag * mid * mid:
            lo = mid
        else:
            hi = mid
    return lo


@numba.njit(cache=True)
def wrap_angle(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@numba.njit(cache=True)
def autopilot(h, g, reference, closed_loop, integrals, u, depth, depth_rate, pitch, yaw, q, r,
              dt):
    """Actuator commands (rpm, rudder rad, stern planes rad) for one physics step.

    Args:
        reference: (3,) speed (m/s), heading (rad) and depth (m) for closed-loop channels,
            or rpm, rudder and stern-plane angle for open-loop ones.
        closed_loop: (3,) bool, which channels the autopilot drives.
        integrals: (3,) integrator states, updated in place.
    """
    return autopilot_into(h, g, reference, closed_loop, integrals, u, depth, depth_rate,
                          pitch, yaw, q, r, dt, reference.copy())


@numba.njit(cache=True)
def autopilot_into(h, g, reference, closed_loop, integrals, u, depth, depth_rate, pitch, yaw,
                   q, r, dt, cmd):
    """``autopilot`` into ``cmd`` (3,), which holds ``reference`` on entry, and returned:
    the physics loop's, so that a step allocates nothing."""
    speed = max(abs(u), 0.5)
    t_scale = g.length / speed
    if closed_loop[0] and g.hold_rpm:
        cmd[0] = math.copysign(feedforward_rpm(h, abs(reference[0]), linear_damping=True),
                               reference[0])
    elif closed_loop[0]:
        err = reference[0] - u
        integrals[0] = min(max(integrals[0] + err * dt, -2.0 * g.length), 2.0 * g.length)
        target = reference[0] + g.speed_p * err + g.speed_i * integrals[0] / t_scale
        cmd[0] = math.copysign(feedforward_rpm(h, abs(target)), target)
    if closed_loop[1]:
        err = wrap_angle(reference[1] - yaw)
        if abs(err) < 0.2:  # integrate near the target only, so turns do not wind it up
            integrals[1] = min(max(integrals[1] + err * dt / t_scale, -5.0), 5.0)
        braking = g.heading_d * t_scale * abs(r) / g.heading_p
        if g.full_rudder_turns and abs(err) >= 0.2 and abs(err) > braking:
            cmd[1] = math.copysign(math.pi, err)  # the servo stops it at the rudder limit
        else:
            cmd[1] = g.heading_p * err + g.heading_i * integrals[1] - g.heading_d * t_scale * r
    if closed_loop[2]:
        err = (reference[2] - depth) / g.length
        if abs(err) < 0.2:
            integrals[2] = min(max(integrals[2] + err * dt / t_scale, -10.0), 10.0)
        pitch_ref = -(g.depth_p * err + g.depth_i * integrals[2]) + g.depth_d * depth_rate / speed
        pitch_ref = min(max(pitch_ref, -g.pitch_max), g.pitch_max)
        cmd[2] = g.pitch_p * (pitch - pitch_ref) + g.pitch_d * t_scale * q
    return cmd


@numba.njit(cache=True)
def servo(h, actuators, cmd, dt):
    """Advance the actuators one step toward ``cmd`` (in place): a first-order shaft, and
    fins with a time constant, a rate limit and an angle limit."""
    rpm_cmd = min(max(cmd[0], -h.rpm_max), h.rpm_max)
    actuators[0] += (rpm_cmd - actuators[0]) * (1.0 - math.exp(-dt / h.shaft_tau))
    for i in (1, 2):
        limit = h.rudder_max if i == 1 else h.planes_max
        target = min(max(cmd[i], -limit), limit)
        rate = (target - actuators[i]) / h.fin_tau
        rate = min(max(rate, -h.fin_rate), h.fin_rate)
        step = rate * dt
        if abs(step) > abs(target - actuators[i]):
            step = target - actuators[i]
        actuators[i] += step
    return actuators

