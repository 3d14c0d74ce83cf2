"""Simulated SMM plant: RK4 integration, sensor noise, disturbances, stops, actuator models."""

from smm_sim.plant import (
    DISTURBANCE_MODELS,
    PAPER_VALVE_RESPONSE_TIMES,
    DisturbanceModel,
    GroundTruth,
    Measurement,
    PlantConfig,
    SimulatedPlant,
    disturbance_torque,
    eq46_disturbance,
    valve_time_constants_from_response_times,
)

__all__ = [
    "DISTURBANCE_MODELS",
    "PAPER_VALVE_RESPONSE_TIMES",
    "DisturbanceModel",
    "GroundTruth",
    "Measurement",
    "PlantConfig",
    "SimulatedPlant",
    "disturbance_torque",
    "eq46_disturbance",
    "valve_time_constants_from_response_times",
]
