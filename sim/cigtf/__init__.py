"""The CIGTF gyrocompassing test's world (report 001): two-axis fixture and torque-to-balance
SDF gyro.
"""
