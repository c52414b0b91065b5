"""Flights of the rotor-level vehicle with an estimator in the loop (docs/vehicle.md):
a controller flies the vehicle model on what the estimator makes of the sensors, and the flight
becomes a recording that every command reads. Layer 2: it joins the controllers, the estimators
and the simulator's sensors."""

from quadest.flight.common import SIM_RATE_HZ, Flight, FlightParams, position_gain
from quadest.flight.fly import fly, fly_many, resample
from quadest.flight.spec import CONTROLLERS, DEFAULT_DURATION, FLIGHT_SCENARIOS, FlightSpec, in_loop_estimators
from quadest.flight.summary import campaign_table, offline_errors

__all__ = [
    "CONTROLLERS",
    "DEFAULT_DURATION",
    "Flight",
    "FlightParams",
    "FlightSpec",
    "FLIGHT_SCENARIOS",
    "SIM_RATE_HZ",
    "campaign_table",
    "fly",
    "fly_many",
    "in_loop_estimators",
    "offline_errors",
    "position_gain",
    "resample",
]
