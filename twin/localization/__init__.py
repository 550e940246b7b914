"""Cooperative positioning (CPS): solvers, covariance propagation and the step record."""
