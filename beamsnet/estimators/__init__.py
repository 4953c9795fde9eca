"""Estimators: least squares and calibrations, robust least squares, the INS/DVL filter,
missing-beam regressors and the networks, each declared in the registry by its own
module (``registry``: ``specs()``, ``spec(name)``)."""

from beamsnet.estimators.registry import (
    Needs,
    Spec,
    checked,
    models,
    network_names,
    predicted,
    register,
    short_name,
    spec,
    specs,
    unregister,
)

__all__ = ["Needs", "Spec", "checked", "models", "network_names", "predicted", "register",
           "short_name", "spec", "specs", "unregister"]
