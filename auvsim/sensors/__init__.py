"""Sensor error models: true signals from the simulation in, measurements out."""
