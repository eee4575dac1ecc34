"""The ESG readout laboratory's calibration command and record."""
