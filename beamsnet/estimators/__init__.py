"""Estimators: least squares and calibrations, the INS/DVL filter, missing-beam
regressors and the networks."""
