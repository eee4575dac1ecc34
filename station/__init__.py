"""The rack: configuration, links, drivers, clock, records and the command line."""

__version__ = "0.1.0"  # what `station --version` says when the package is not installed
