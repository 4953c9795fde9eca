"""Pressure depth sensor: the depth every AUV measures from its hull's pressure port.

Per sample k, at the body origin (the port is taken to sit there)::

    depth[k] = q(true_depth[k] + bias + n[k]),   n[k] ~ N(0, noise_std^2)
    q(x)     = resolution * round(x / resolution)   (no rounding when resolution is 0)

``bias`` ~ N(0, bias_std^2) is drawn once per mission: the offset left after the
sensor's calibration, within its stated accuracy. The pressure-to-depth conversion is
taken as exact (a real unit's density and gravity model adds a small scale error, not
modelled). Units: m, positive down (NED z).

Samples fall on IMU samples that are whole multiples of ``imu.rate_hz / depth.rate_hz``,
the first at t = 0.
"""

from __future__ import annotations

import numpy as np

from auvsim.sensors import Attr, Field, Sensor, sample_rows, samples_in

CHUNK = 1024  # noise samples drawn ahead at a time


class PressureDepth(Sensor):
    """The depth sensor plugin (``auvsim.config.DepthConfig``)."""

    name = "depth"
    section = "depth"
    streams = ("depth_parameters", "depth_noise")
    fields = (
        Field("depth/time", (), "f", "depth", "s", "sample times"),
        Field("depth/depth", (), "f", "depth", "m", "measured depth of the body origin"),
    )
    attributes = (
        Attr("depth_rate_hz", (), "Hz", low=0, strict=True),
        Attr("depth_bias", (), "REALISED offset, m"),
        Attr("depth_noise_std", (), "m"),
        Attr("depth_resolution", (), "m (0: not quantised)"),
    )
    since_version = 3

    def __init__(self, config, platform, parameters):
        self.config = config.depth
        self.every_imu = self.every(config)
        self.bias = self.config.bias_std * float(parameters.standard_normal())
        self._rng, self._ahead, self._at = None, np.zeros(0), 0

    def _noise(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """The next ``n`` samples of ``noise_std * N(0, 1)`` from ``rng``: drawn ahead,
        ``CHUNK`` at a time (the environment measures one sample a step, and a draw's cost
        per call is most of it). A generator reads forward only, so the numbers are the
        ones drawn a block at a time; a new ``rng`` starts afresh."""
        if rng is not self._rng:
            self._rng, self._ahead, self._at = rng, np.zeros(0), 0
        if self._at + n > len(self._ahead):
            drawn = self.config.noise_std * rng.standard_normal(max(n, CHUNK))
            self._ahead, self._at = np.concatenate([self._ahead[self._at:], drawn]), 0
        self._at += n
        return self._ahead[self._at - n:self._at]

    @classmethod
    def describe(cls, mission):
        a = mission.attrs
        return [f"    depth sensor {a['depth_rate_hz']:g} Hz ({mission.depth.rows} samples): "
                f"offset {a['depth_bias']:.4g} m, noise std {a['depth_noise_std']:g} m, "
                f"resolution {a['depth_resolution']:g} m"]

    def rows(self, n_imu):
        return {"depth": samples_in(n_imu, self.every_imu)}

    def attrs(self):
        c = self.config
        return dict(depth_rate_hz=c.rate_hz, depth_bias=self.bias,
                    depth_noise_std=c.noise_std, depth_resolution=c.resolution)

    def measure(self, truth, rng):
        rows = sample_rows(truth.first, len(truth.time), self.every_imu)
        true = truth.position_ned[rows, 2]
        depth = true + self.bias + self._noise(rng, len(true))
        if self.config.resolution > 0:
            depth = self.config.resolution * np.round(depth / self.config.resolution)
        return {"depth/time": truth.time[rows], "depth/depth": depth}


SENSOR = PressureDepth
