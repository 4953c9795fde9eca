"""Scripted scenarios: what the autopilots are asked to do over time.

A scenario gives the initial state and, for any block of times, the references of the
three channels (speed, heading, depth when closed loop; actuator commands when open loop).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .config import ScenarioConfig


@dataclass(frozen=True)
class Straight:
    """Constant speed, heading and depth, starting on the heading and at the depth."""

    config: ScenarioConfig
    closed_loop: tuple[bool, bool, bool] = (True, True, True)

    def initial_state(self) -> dict:
        c = self.config
        start = c.speed if c.start_speed is None else c.start_speed
        return dict(position_ned=(0.0, 0.0, c.depth), yaw=math.radians(c.heading_deg),
                    velocity_body=(start, 0.0, 0.0))

    def references(self, t: np.ndarray) -> np.ndarray:
        """(N, 3) speed (m/s), heading (rad) and depth (m) at times ``t`` (s)."""
        c = self.config
        return np.tile([c.speed, math.radians(c.heading_deg), c.depth], (len(t), 1))


SCENARIO_TYPES = {"straight": Straight}


def make_scenario(config: ScenarioConfig) -> Straight:
    return SCENARIO_TYPES[config.name](config)
