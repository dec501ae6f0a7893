"""Control side of the platform: controllers, trajectory planner, road geometry."""
