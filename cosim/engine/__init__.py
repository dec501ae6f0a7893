"""The lockstep core, with no I/O: master, step order, signal store and layout, wiring, value checks, pacing, the start-up clock, and the `HostedComponent` contract the transports implement.

Imports nothing from transport, results, figures, analysis or cli (an import-linter contract).
"""
