"""Scenario files of the paper's experiments and the results matrix (scenarios.matrix)."""
