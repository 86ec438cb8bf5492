"""Simulation: MRP algebra, rigid-body dynamics, fault sampling, sensors and the rollout loop."""
