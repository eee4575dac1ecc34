"""The CIGTF gyrocompassing test's command and record."""
