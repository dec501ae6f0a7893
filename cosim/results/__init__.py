"""The run folder: recorder and its spool, CSV writer, manifest, recovery of a killed run.
"""
