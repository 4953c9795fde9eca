"""The DVL's beam geometry, as readers of a dataset need it: the beam matrix of a beam
angle and the least-squares velocity of a ping's beams (3 or 4 valid).

The code is the DVL model's (``auvsim.sensors.dvl``), named here so that what reads the
data (beamsnet among others) depends on the dataset API, not on the simulator's sensors.
"""

from auvsim.sensors.dvl import beam_matrix, least_squares

__all__ = ["beam_matrix", "least_squares"]
