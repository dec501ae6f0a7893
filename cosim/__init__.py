"""cosim: a co-simulation master for closed-loop vehicle control (FMU plants, Zenoh components)."""

__version__ = "0.1.0"
