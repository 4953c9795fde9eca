"""beamsnet: BeamsNetV1/V2 (Cohen & Klein 2022) trained and evaluated on auvsim datasets.

The networks regress the DVL's velocity (m/s, DVL frame) from its raw beam velocities,
helped by the IMU samples between pings (V1) or the past pings' beams (V2). The package
cuts samples from a dataset (``data``), defines the networks (``models``), trains them
with the paper's protocol (``train``; ``TrainConfig`` and its named ``PROFILES`` hold
every training default), compares them with least squares, an affine calibration and a
Kalman filter (``baselines``, ``metrics``, ``evaluate``), and runs the paper's experiments
and a manoeuvre stress test end to end (``experiment``, ``reproduce``, ``stress``,
``cli``). Frames, units and names are auvsim's (see ``auvsim``'s docstring).
"""
