"""The rack: configuration, links, drivers, clock, records and the command line."""
