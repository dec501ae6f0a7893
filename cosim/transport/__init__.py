"""How Python components are hosted: in the master's process (`inproc`) or one OS process each over Zenoh (`zenoh`).
"""
