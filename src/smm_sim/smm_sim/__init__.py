"""Simulated SMM plant: RK4 integration, sensor noise, disturbances, stops, actuator models."""
