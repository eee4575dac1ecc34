"""The ISU calibration laboratory's commands: the calibration day and the alignments, their
truth and plots.
"""
