"""The DVL's beam geometry, as readers of a dataset need it: the beam matrix of a beam
angle, the least-squares velocity of a ping's beams (3 or 4 valid) and its error velocity
(and the white beam noise a logged error velocity shows),
which beams measured (``usable_beams``), a ping's ``Mode`` codes (``dvl/mode``), and the
velocity of the DVL point in its own frame from the body's (``DvlGeometry.velocity``, the
lever arm included).

The code is the DVL model's (``auvsim.sensors.dvl``), named here so that what reads the
data (beamsnet among others) depends on the dataset API, not on the simulator's sensors.
"""

from auvsim.sensors.dvl import (
    DvlGeometry,
    Mode,
    beam_matrix,
    beam_noise_from_error_velocity,
    error_velocity,
    least_squares,
    usable_beams,
)

__all__ = ["DvlGeometry", "Mode", "beam_matrix", "beam_noise_from_error_velocity",
           "error_velocity", "least_squares", "usable_beams"]
