"""Check-sheet procedures of the strapdown ISU calibration laboratory (report 000): survey,
turn-on, calibration charts, alignment.
"""
