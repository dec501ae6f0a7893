"""Reading run folders back: run data, metrics, cone hits. Never imports a transport.
"""
