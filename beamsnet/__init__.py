"""beamsnet: BeamsNetV1/V2 (Cohen & Klein 2022) trained and evaluated on auvsim datasets.

The networks regress the DVL's velocity (m/s, DVL frame) from its raw beam velocities,
helped by the IMU samples between pings (V1) or the past pings' beams (V2). The package
cuts samples from a dataset (``data``), holds the estimators (``estimators``: least
squares and calibrations, the INS/DVL filter, missing-beam regressors, the networks),
trains the networks with the paper's protocol (``training``; ``TrainConfig`` and its
named ``PROFILES`` hold every training default), scores them (``metrics``,
``evaluate``), and runs the paper's experiments, the manoeuvre stress test and the fault
sweep end to end (``experiments``). Frames, units and names are auvsim's (see
``auvsim``'s docstring).
"""

from auvsim.lazy import exports

# What users import, from the top level; loaded when first asked for (torch is heavy).
# Not ``evaluate``: that name is the module ``beamsnet.evaluate``, and a function of the
# same name here made ``beamsnet.evaluate`` the one or the other by the order of imports
# (``from beamsnet.evaluate import evaluate``).
_PUBLIC = {
    "load_windows": "beamsnet.data", "split": "beamsnet.data",
    "TrainConfig": "beamsnet.training.config", "PROFILES": "beamsnet.training.config",
    "train": "beamsnet.training.train", "load": "beamsnet.training.checkpoints",
    "predict": "beamsnet.training.train", "estimate": "beamsnet.evaluate",
}
__all__ = list(_PUBLIC)

_load, __dir__ = exports(__name__, _PUBLIC, globals())


def __getattr__(name: str) -> object:
    """A public name, loaded; where it needs PyTorch and PyTorch is not installed (a plain
    install leaves out the ``learn`` extra), the error says what to install, as the
    command line does (``beamsnet.estimators.registry.NO_TORCH``)."""
    try:
        return _load(name)
    except ModuleNotFoundError as e:
        if e.name != "torch":
            raise
        from beamsnet.estimators.registry import NO_TORCH

        raise ModuleNotFoundError(f"beamsnet.{name}: {NO_TORCH}", name="torch") from None
