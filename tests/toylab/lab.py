"""The toy laboratory's declaration (its registry entry) and its command, ``station toy-bath``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any

import typer

from laboratory.seeded import Seeded, SerialParts, serial_laboratory
from toylab.rack import ThermometerDriver, ToyDrivers, ToyRack
from toylab.world import ToyParams

DRIVERS: dict[str, Any] = {"thermometer": ThermometerDriver}


def run_bath(seed: int, out: Path, links: Path | None = None, n: int = 10) -> dict:
    """T-1 into ``out`` (journal, sheets, toy.json) on a local or a served toy rack."""
    from laboratory.connect import connect, journaled_run
    from laboratory.record import write_json, write_sheets
    from laboratory.rundir import prepare
    from toylab.procedure import bath_temperature

    prepare(out, False, links)
    conn = connect(LAB, Seeded(ToyParams(), seed), links)
    world = conn.coefficient_world
    with journaled_run(out, conn, seed=seed, test="toy-bath") as (run, extra, _):
        res = bath_temperature(conn.drivers, run, n)
        res["truth_k"] = LAB.truth(world)["bath_k"] if world is not None else None
        write_sheets(out, run)
        write_json(out / "toy.json", {**res, **extra})
    return res


def add_commands(app: Any) -> None:
    @app.command("toy-bath")
    def toy_bath(
        out: Annotated[Path, typer.Option("--out", help="new run directory")],
        seed: Annotated[int, typer.Option("--seed", help="run seed")] = 1,
        links: Annotated[Path | None, typer.Option("--links", help="a served toy rack")] = None,
        readings: Annotated[int, typer.Option("--readings", min=2)] = 10,
    ) -> None:
        """The toy laboratory's T-1: the bath temperature."""
        res = run_bath(seed, out, links, readings)
        typer.echo(json.dumps(res))


LAB = serial_laboratory(
    "toy", "toy laboratory (one thermometer)", "(no config)",
    lambda: SerialParts(lambda path: ToyParams(), ToyRack, DRIVERS, ToyDrivers),
    truth=lambda world: {"bath_k": world.true_k}, add_commands=add_commands)
