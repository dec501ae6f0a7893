"""Runs over several hosts: the worker agent, the master's client of it, their protocol, placement, deployment files (endpoints, TLS, ACL), the router.
"""
