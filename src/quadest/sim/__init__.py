"""The flight and sensor simulator: scenarios, presets and sensor models (docs/simulator.md)."""

from quadest.sim.params import PRESETS, SimConfig, param_table, preset_config
from quadest.sim.simulator import aero_model, aero_model_of, build_config, simulate
from quadest.sim.truth import PRESCRIBED_SCENARIOS

__all__ = [
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
