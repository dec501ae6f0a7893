"""Road and path geometry: planar paths by arc length, splines, road builders, projection on a trajectory window.
"""
