"""CIGTF standard gyrocompassing accuracy test (report 001): scale factor, data analysis, tests."""
