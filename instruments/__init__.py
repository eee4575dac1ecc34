"""Virtual laboratory instruments: state machines on simulated time, each with a wire protocol.

An instrument reads the world from :mod:`sim` and talks bytes (serial) or frames (CAN);
it never knows how those travel (station.links does that).
"""
