"""Configuration of each laboratory's rack (sites, units, noise, links, faults) and the one
TOML reader.
"""
