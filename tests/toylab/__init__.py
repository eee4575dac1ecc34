"""A toy fourth laboratory (one thermometer, one procedure), kept outside the project's
packages to show that a laboratory is one package plus one registry entry
(``STATION_LABORATORIES=toy=toylab.lab:LAB``): tests/test_registry.py."""
