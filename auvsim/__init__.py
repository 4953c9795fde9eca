"""auvsim: a MuJoCo torpedo-AUV simulator that produces labelled DVL/IMU datasets.

Conventions (a contract: the HDF5 files and every public function follow them):

* World frame NED (x north, y east, z down); body frame FRD (x forward, y starboard,
  z down). Inside MuJoCo the world is north-west-up and the body forward-left-up; the two
  differ by a rotation of pi about x, so converting flips the sign of the y and z
  components (of vectors, and of a quaternion's vector part). ``auvsim.physics.frames``
  holds every conversion; only ``auvsim.physics.vehicle``, ``auvsim.physics.hydro`` (reading
  the model) and ``auvsim.world.seafloor`` (ray casts) see MuJoCo coordinates.
* Quaternions ``[w, x, y, z]`` rotate body vectors into NED. Euler angles are roll,
  pitch, yaw (ZYX).
* SI units: m, s, rad, m/s, m/s^2, rad/s, N, N m. Degrees only in CLI and config inputs
  whose names end in ``_deg``. Propeller shaft speed in rpm.
* Specific force ``f = a - g`` in body axes: at rest and level an accelerometer reads
  ``(0, 0, -9.81)`` m/s^2, the vehicle model's gravity. With a geographic origin
  (``Config.location``) the NED frame turns with the Earth: ``f = C^T (a + 2 w_ie x v -
  g_n)``, g_n the WGS-84 normal gravity there (``(0, 0, -9.7955)`` at rest off Haifa).
* Array names: ``position_ned``, ``velocity_ned``, ``velocity_body`` (at the body origin,
  the centre of buoyancy), ``quaternion``, ``angular_rate`` (body, relative to the NED
  frame; with a geographic origin a gyro reads it plus the Earth's rate, ``C^T w_ie``),
  ``specific_force`` (body, at the IMU site: what an ideal accelerometer reads). Time is
  the first axis of every array.
"""

from auvsim.lazy import exports

__version__ = "0.1.0"

# What users import, from the top level; each is loaded when first asked for, so that
# ``import auvsim`` stays light (MuJoCo and numba load with the first name that needs them).
_PUBLIC = {
    "Config": "auvsim.config", "MissionConfig": "auvsim.config",
    "ScenarioConfig": "auvsim.config",
    "load_config": "auvsim.config",
    "preset": "auvsim.runs.presets", "generate": "auvsim.runs.generate",
    "open_dataset": "auvsim.data.reader",
    "Vehicle": "auvsim.physics.vehicle", "Seafloor": "auvsim.world.seafloor",
    "AuvEnv": "auvsim.envs.env", "ManeuverPolicy": "auvsim.envs.env",
    "EpisodeRecorder": "auvsim.envs.env", "AuvVectorEnv": "auvsim.envs.vector",
    "AuvsimError": "auvsim.errors",
}
__all__ = ["__version__", *_PUBLIC]

__getattr__, __dir__ = exports(__name__, _PUBLIC, globals())


def _register_environment() -> None:
    """Register ``auvsim/AUV-v0`` with gymnasium, by name only: ``auvsim.envs.env`` (MuJoCo,
    numba) is imported when the environment is made. ``gymnasium.make_vec`` makes an
    ``auvsim.envs.vector.AuvVectorEnv`` (worker processes over shared memory) by default or
    with ``vectorization_mode="vector_entry_point"``; "sync" and "async" as usual."""
    import gymnasium

    if "auvsim/AUV-v0" not in gymnasium.registry:
        gymnasium.register(id="auvsim/AUV-v0", entry_point="auvsim.envs.env:AuvEnv",
                           vector_entry_point="auvsim.envs.vector:AuvVectorEnv")


_register_environment()
