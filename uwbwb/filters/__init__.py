"""Estimators: Kalman filters (via :mod:`.kalman`, the filterpy edge), particle filters,
nonlinear least squares, INS mechanization. Import the sub-module you need."""
