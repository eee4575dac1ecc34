"""The application above the procedures: the laboratories' registry, commands and CLI, the
run's record, compare and check.
"""
