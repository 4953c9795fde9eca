"""The error vocabulary: one base class, caught once at the CLI boundary."""


class AuvsimError(Exception):
    """Base class of every error auvsim raises on purpose."""


class ConfigError(AuvsimError, ValueError):
    """A configuration value or command-line option is invalid."""


class DatasetError(AuvsimError):
    """A file is not an auvsim dataset, is corrupt, or has another format version."""


class SimulationError(AuvsimError):
    """A mission cannot go on as configured (for example the vehicle reached the seafloor)."""
