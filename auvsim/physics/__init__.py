"""The vehicle and the water: frames, hydrodynamics, actuators, autopilot, manoeuvres."""
