"""The flight and sensor simulator: scenarios, presets, sensor models and rotor failures
(docs/simulator.md, docs/vehicle.md)."""

from quadest.sim.faults import FAILURE_MODES, Failure
from quadest.sim.params import PRESETS, SimConfig, param_table, preset_config
from quadest.sim.simulator import aero_model, aero_model_of, build_config, simulate
from quadest.sim.truth import PRESCRIBED_SCENARIOS

__all__ = [
    "FAILURE_MODES",
    "Failure",
    "PRESETS",
    "PRESCRIBED_SCENARIOS",
    "SimConfig",
    "aero_model",
    "aero_model_of",
    "build_config",
    "param_table",
    "preset_config",
    "simulate",
]
