"""Check-sheet procedures of the laboratories and the computations they call.

A procedure receives a ``Station`` (drivers and the clock) and a ``Run`` (the journal and
the check-sheets being ticked). It never touches ``sim`` or ``instruments``.
"""
