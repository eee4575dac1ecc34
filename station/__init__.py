"""The rack floor: links, drivers and each laboratory's driver set, the clock, errors,
configuration, rack assembly and real-time serving. The application (commands, records,
the command line) is the ``laboratory`` package above the procedures."""

__version__ = "0.1.0"  # what `station --version` says when the package is not installed
