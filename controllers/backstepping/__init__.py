"""The paper's backstepping control laws (longitudinal eq. 7, lateral eq. 9-13) and the controller component that combines them.

Scenarios name the component `controllers.backstepping:BacksteppingController`.
"""
from controllers.backstepping.component import BacksteppingController

__all__ = ["BacksteppingController"]
