"""Scenario files: the typed schema, YAML loading with line numbers, cross-field checks, source schemas, the JSON schema.

Imports nothing from the engine or the transports: a scenario is data.
"""
