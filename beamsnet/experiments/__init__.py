"""Experiments end to end: the paper's, manoeuvre stress, sensor faults, sim to real."""
