"""Trajectory planning: the planner component, manoeuvres, speed profiles, finite-time stops.

Scenarios name the component `controllers.planning:Planner`.
"""
from controllers.planning.planner import Planner

__all__ = ["Planner"]
