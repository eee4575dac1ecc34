"""The ESG readout laboratory (report 004) as the registry sees it.

Nothing heavy is imported here (the registry's rule): each callable imports what it uses.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from laboratory.seeded import SerialParts, serial_laboratory

if TYPE_CHECKING:
    import typer

    from sim.esg.world import EsgWorld


def _parts() -> SerialParts:
    from station.config.esg import load_esg_params
    from station.drivers.esg import EsgDrivers
    from station.racks.esg import INSTRUMENTS, EsgRack

    return SerialParts(load_esg_params, EsgRack, INSTRUMENTS, EsgDrivers)


def truth(world: EsgWorld) -> dict[str, float]:
    """The static truth an ESG calibration estimates: pickoff 1's coning about the spindle."""
    from laboratory.esg.truth import true_pickoff1_coning_arcsec

    return {"pickoff1_coning_arcsec": true_pickoff1_coning_arcsec(world)}


def _commands(app: typer.Typer) -> None:
    from laboratory.esg.cli import add_commands

    add_commands(app)


LAB = serial_laboratory(
    "esg", "ESG readout laboratory (report 004)",
    "TOML with an [esg] section (site, rotor, [esg.pattern], [esg.signal])", _parts, truth,
    _commands)
