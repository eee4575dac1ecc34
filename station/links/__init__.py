"""Links between drivers and instruments, chosen by URL: sim:// (virtual), pty/device, CAN."""

import serial

if "station.links" not in serial.protocol_handler_packages:
    serial.protocol_handler_packages.append("station.links")
