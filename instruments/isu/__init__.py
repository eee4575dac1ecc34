"""Virtual instruments of the ISU calibration laboratory (report 000): table controller, patch
panel, counters, autocollimators, bubble levels, oscillator panel, IEU.
"""
