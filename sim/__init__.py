"""The physical world of the laboratories: time, Earth, environment, fixtures, instruments' physics.

SI units throughout (seconds, radians, m/s^2); lab units appear only in configuration and
are converted once, in :mod:`sim.units`.
"""
