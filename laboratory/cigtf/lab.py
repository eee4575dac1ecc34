"""The CIGTF gyrocompassing test (report 001) as the registry sees it.

Nothing heavy is imported here (the registry's rule): each callable imports what it uses.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from laboratory.seeded import SerialParts, serial_laboratory

if TYPE_CHECKING:
    import typer

    from sim.cigtf.world import CigtfWorld


def _parts() -> SerialParts:
    from station.config.cigtf import load_cigtf_params
    from station.drivers.cigtf import CigtfDrivers
    from station.racks.cigtf import INSTRUMENTS, CigtfRack

    return SerialParts(load_cigtf_params, CigtfRack, INSTRUMENTS, CigtfDrivers)


def truth(world: CigtfWorld) -> dict[str, float]:
    """The fixture's true azimuth error the test measures (eq. 26, theta, arcsec)."""
    return {"theta_arcsec": world.truth_theta_arcsec()}


def _commands(app: typer.Typer) -> None:
    from laboratory.cigtf.cli import add_commands

    add_commands(app)


LAB = serial_laboratory(
    "cigtf", "CIGTF gyrocompassing test (report 001)",
    "TOML with a [cigtf] section (site, gyro model, fixture)", _parts, truth, _commands)
