"""Assembling and executing runs: prepare, start, execute, abort, validate without running, pre-started processes, progress, sweeps.
"""
