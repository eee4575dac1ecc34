"""Check-sheet procedures of the laboratories and the computations they call.

A procedure receives its laboratory's driver set (``IsuDrivers``, ``CigtfDrivers``,
``EsgDrivers``: drivers and the clock) and a ``Run`` (the journal and the check-sheets being
ticked). It never touches ``sim`` or ``instruments``. Shared here: the runner, the journal
and the check-sheet; each laboratory's procedures in ``isu/``, ``cigtf/``, ``esg/``.
"""
