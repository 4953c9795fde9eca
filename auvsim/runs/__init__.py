"""Runs: named presets, one mission, generation on one machine or a Dask cluster."""
