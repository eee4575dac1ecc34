"""The start of a `station` run command: the cyclic garbage collector deferred while the
command imports what it runs (issue 17).

Importing a command's modules makes some hundred thousand objects that live as long as the
process, and almost no garbage; the collector, left on, traverses each of them in its
young-generation passes and once more in a full one: 0.04-0.05 s of every run command
(gc.callbacks, `station day`, the gyrocompassing test and the ESG calibration alike).
``defer`` (the script, before its imports) turns it off; ``resume`` (laboratory.connect,
where every run command starts its rack) freezes what exists, which later passes skip, and
turns it on again for the run, however long it lasts (a rehearsal over links runs for
hours). A process that never called ``defer`` (a test, a library user) is left alone.
"""

from __future__ import annotations

import gc

_deferred = False


def defer() -> None:
    """No cyclic collection until ``resume`` (the collector was on)."""
    global _deferred
    if gc.isenabled():
        gc.disable()
        _deferred = True


def resume() -> None:
    """What the imports made frozen, and the collector on again, if ``defer`` turned it
    off; else nothing."""
    global _deferred
    if _deferred:
        _deferred = False
        gc.freeze()
        gc.enable()
