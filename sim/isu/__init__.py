"""The ISU calibration laboratory's world (report 000): site, pier, four-axis table, ISU,
master oscillator, pulse lines.
"""
