"""Rack assembly: each laboratory's simulated world and instruments registered for its links,
and the drivers opened on them.
"""
