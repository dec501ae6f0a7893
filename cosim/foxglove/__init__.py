"""Foxglove outputs: run.mcap written from a run folder, and a live Foxglove WebSocket server.

Both use Foxglove's well-known schemas through the `foxglove-sdk` package (the
`foxglove` extra), with the same channels (`cosim.foxglove.channels`).
"""
