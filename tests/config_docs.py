"""Random and mutated configuration documents for the three laboratories' loaders, and the
checks every outcome must pass (tests/test_config_fuzz.py; bench/fuzz_config.py runs many
more).

A document starts valid (the ISU default or a part of it, a [cigtf] or [esg] section with
some of its fields) and gets a few mutations: fields deleted, renamed, retyped, set to
extreme, negative, nan or inf values, unknown or misspelt fields and sections, another
laboratory's section, deep nesting, and byte-level damage (invalid UTF-8, flipped bytes,
truncation, random bytes). ``outcome`` loads it and returns what happened; a traceback
escapes as the exception it is.
"""

from __future__ import annotations

import copy
import datetime as dt
import json
import math
import random
import re
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sim.cigtf.world import CigtfParams
from sim.esg.world import EsgParams
from station.config.cigtf import CigtfConfig, load_cigtf_params
from station.config.esg import EsgConfig, PatternConfig, SignalConfig, load_esg_params
from station.config.file import LABORATORIES
from station.config.isu import FAULT_INSTRUMENTS, ConfigError, default_dict, load_config

LABS = ("ISU", "CIGTF", "ESG")
_PLAIN = re.compile(r"[A-Za-z0-9_-]+")


@dataclass(frozen=True)
class Raw:
    """Text put into the document as it is (deep nesting the writer need not recurse)."""

    text: str


# ----------------------------------------------------------------------------- TOML writer


def _key(k: str) -> str:
    return k if _PLAIN.fullmatch(k) else json.dumps(k)


def _value(v: Any) -> str:
    if isinstance(v, Raw):
        return v.text
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, dt.datetime | dt.date | dt.time):
        return v.isoformat()
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def dumps(doc: dict[str, Any]) -> str:
    """TOML text of a document: one ``key = value`` line per top-level name."""
    return "".join(f"{_key(k)} = {_value(v)}\n" for k, v in doc.items())


# ----------------------------------------------------------------------------- documents


def _cigtf_fields() -> dict[str, Any]:
    p = CigtfParams()
    return {k: getattr(p, k) for k in CigtfConfig.model_fields if k not in ("limits", "eq27")}


def _esg_fields() -> dict[str, Any]:
    p = EsgParams()
    top = {k: getattr(p.rotor, k) for k in EsgConfig.model_fields
           if k not in ("pattern", "signal", "limits", "reduction", "procedure")}
    top["pattern"] = {k: getattr(p.pattern, k) for k in PatternConfig.model_fields}
    top["signal"] = {k: getattr(p.signal, k) for k in SignalConfig.model_fields}
    return top


def _subset(rng: random.Random, table: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in table.items() if rng.random() < 0.6}


def base_document(rng: random.Random, lab: str) -> dict[str, Any]:
    """A valid document of ``lab``: all of it or a part."""
    if lab == "ISU":
        doc = default_dict()
        if rng.random() < 0.5:  # a user file names only what it changes
            doc = {k: v for k, v in doc.items() if rng.random() < 0.4}
        return doc
    if lab == "CIGTF":
        return {"cigtf": _subset(rng, _cigtf_fields())}
    esg = _esg_fields()
    out = _subset(rng, {k: v for k, v in esg.items() if not isinstance(v, dict)})
    for sub in ("pattern", "signal"):
        if rng.random() < 0.6:
            out[sub] = _subset(rng, esg[sub])
    return {"esg": out}


# ----------------------------------------------------------------------------- mutations

EXTREMES: tuple[Any, ...] = (
    0, -1, 0.0, -0.0, 1e300, -1e300, 1e-300, -1e-300, 1e308, -1e308, float("nan"),
    float("inf"), float("-inf"), 2**63, -(2**63), 2**64, 10**30, 5e-324, 1.7976931348623157e308,
)
OTHER_VALUES: tuple[Any, ...] = (
    "", "abc", "1.0", "sim://x", "\n", "\x00", True, False, [], [1.0], [1.0, 2.0, 3.0],
    [[0.0, 90.0]], {}, {"x": 1}, dt.datetime(2026, 1, 1, 12, 0), dt.date(2026, 1, 1),
    Raw("12:00:00"),  # a TOML local time
)
TYPOS = ("cigft", "esgg", "sit", "enviroment", "tabel", "isuu", "osc", "instrument",
         "link", "fault", "Seed", "ESG", "Cigtf", "site.latitude_deg")


def _paths(node: Any, at: tuple = ()) -> list[tuple]:
    """Every path to a value (tables, arrays and leaves) below ``node``."""
    out = []
    if isinstance(node, dict):
        for k, v in node.items():
            out.append((*at, k))
            out += _paths(v, (*at, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out.append((*at, i))
            out += _paths(v, (*at, i))
    return out


def _tables(node: Any, at: tuple = ()) -> list[tuple]:
    out = [at] if isinstance(node, dict) else []
    if isinstance(node, dict):
        for k, v in node.items():
            out += _tables(v, (*at, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out += _tables(v, (*at, i))
    return out


def _get(doc: Any, path: tuple) -> Any:
    for p in path:
        doc = doc[p]
    return doc


def _typo(rng: random.Random, word: str) -> str:
    w = list(str(word)) or ["x"]
    i = rng.randrange(len(w))
    op = rng.randrange(4)
    if op == 0:
        del w[i]
    elif op == 1:
        w.insert(i, rng.choice("abcdefghijklmnopqrstuvwxyz_"))
    elif op == 2 and len(w) > 1:
        j = min(i + 1, len(w) - 1)
        w[i], w[j] = w[j], w[i]
    else:
        w[i] = w[i].upper() if w[i].islower() else "x"
    out = "".join(w)
    return out if out != word else out + "s"


def _extreme(rng: random.Random, v: Any) -> Any:
    if isinstance(v, int | float) and not isinstance(v, bool) and rng.random() < 0.4:
        return rng.choice((-v, v * 1e6, v * 1e-6, v + 1, v - 1, v * 10, v / 10, -abs(v) - 1))
    return rng.choice(EXTREMES)


def _nesting(rng: random.Random) -> Raw:
    n = rng.choice((3, 9, 40, 200, 500, 990, 1000, 1100, 3000))
    if rng.random() < 0.5:
        return Raw("[" * n + "]" * n)
    return Raw("{a = " * n + "1" + "}" * n)


def mutate(rng: random.Random, doc: dict[str, Any], lab: str) -> dict[str, Any]:
    """One mutation of ``doc`` (a deep copy is changed and returned)."""
    doc = copy.deepcopy(doc)
    paths = _paths(doc)
    op = rng.randrange(9)
    if op == 0 and paths:  # delete a field or table
        p = rng.choice(paths)
        parent = _get(doc, p[:-1])
        del parent[p[-1]]
    elif op == 1 and paths:  # rename a field (a typo)
        p = rng.choice([q for q in paths if isinstance(q[-1], str)] or paths)
        parent = _get(doc, p[:-1])
        if isinstance(parent, dict):
            parent[_typo(rng, p[-1])] = parent.pop(p[-1])
    elif op == 2 and paths:  # retype
        p = rng.choice(paths)
        _get(doc, p[:-1])[p[-1]] = copy.deepcopy(rng.choice(OTHER_VALUES))
    elif op in (3, 4) and paths:  # extreme, negative, nan, inf (the commonest mistake)
        leaves = [q for q in paths if not isinstance(_get(doc, q), dict | list)] or paths
        p = rng.choice(leaves)
        _get(doc, p[:-1])[p[-1]] = _extreme(rng, _get(doc, p))
    elif op == 5:  # an unknown field in some table
        t = _get(doc, rng.choice(_tables(doc)))
        t[_typo(rng, rng.choice(list(t) or ["field"]))] = rng.choice((1.0, "x", True))
    elif op == 6:  # a misspelt or another laboratory's section
        if rng.random() < 0.5:
            name = rng.choice(TYPOS)
        else:
            name = rng.choice([n for k, ns in LABORATORIES.items() if k != lab for n in ns])
        doc[name] = rng.choice(({}, {"latitude_deg": 45.0}, 3, "x"))
    elif op == 7:  # deep nesting
        t = _get(doc, rng.choice(_tables(doc)))
        t[rng.choice(list(t) or ["deep"])] = _nesting(rng)
    elif lab == "ISU":  # rehearsal faults with random fields
        name = rng.choice((*FAULT_INSTRUMENTS, "counter9", "ieu2"))
        fields = {"latency_s": 0.05, "drop_rate": 0.01, "corrupt_rate": 0.001,
                  "silent_after_s": 3600.0, "stall_axis": 2, "stall_after_s": 60.0}
        spec = {k: (_extreme(rng, v) if rng.random() < 0.4 else v)
                for k, v in fields.items() if rng.random() < 0.4}
        if not isinstance(doc.get("faults"), dict):
            doc["faults"] = {}
        doc["faults"][name] = spec
    return doc


def damage(rng: random.Random, raw: bytes) -> bytes:
    """Byte-level damage of a document's text."""
    op = rng.randrange(6)
    b = bytearray(raw)
    i = rng.randrange(len(b) + 1)
    if op == 0:  # invalid UTF-8
        b[i:i] = rng.choice((b"\xff", b"\xc3\x28", b"\xed\xa0\x80", b"\xf8\x88\x80\x80\x80"))
    elif op == 1 and b:  # a flipped byte
        j = rng.randrange(len(b))
        b[j] ^= 1 << rng.randrange(8)
    elif op == 2:  # truncated
        del b[i:]
    elif op == 3:  # random bytes inserted
        b[i:i] = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 20)))
    elif op == 4:  # a line repeated (a duplicate key)
        lines = bytes(b).splitlines(keepends=True)
        if lines:
            k = rng.randrange(len(lines))
            lines.insert(k, lines[k])
        b = bytearray(b"".join(lines))
    else:  # nothing but random bytes
        b = bytearray(rng.randrange(256) for _ in range(rng.randrange(0, 200)))
    return bytes(b)


def document(rng: random.Random, lab: str | None = None) -> tuple[str, bytes]:
    """A laboratory (``lab`` or a random one) and a (usually) mutated document of it."""
    lab = lab or rng.choice(LABS)
    doc = base_document(rng, lab)
    for _ in range(rng.choice((0, 1, 1, 1, 2, 3))):
        doc = mutate(rng, doc, lab)
    raw = dumps(doc).encode("utf-8", "surrogatepass")
    if rng.random() < 0.15:
        raw = damage(rng, raw)
    return lab, raw


# ----------------------------------------------------------------------------- outcomes


LOADERS = {
    "ISU": lambda p: load_config(p),
    "CIGTF": load_cigtf_params,
    "ESG": load_esg_params,
}


def message_problem(msg: str, path: Path, lab: str) -> str | None:
    """What is wrong with a rejection message, or None: it must be one line naming the
    file, and a validation failure must start with a field of the laboratory."""
    if "\n" in msg or "\r" in msg:
        return "more than one line"
    if str(path) not in msg:
        return "does not name the file"
    head = f"configuration in {path}: "
    if msg.startswith("invalid ") and head in msg:
        rest = msg.split(head, 1)[1]
        field = re.split(r"[.: ]", rest, maxsplit=1)[0]
        if field not in LABORATORIES[lab]:
            return f"does not start with a field of the {lab} file: {rest[:60]!r}"
    return None


def exercise(lab: str, params: Any, seed: int, minutes: float = 3.0) -> None:
    """Build the laboratory's rack from accepted params and run its noise processes for a
    few simulated minutes; raise AssertionError if anything is not finite."""
    from station.racks.cigtf import CigtfRack
    from station.racks.esg import EsgRack
    from station.racks.isu import SimulatedRack

    t = np.linspace(0.0, 60.0 * minutes, 37)
    if lab == "ISU":
        with SimulatedRack(params) as rack:
            w = rack.world
            vals = [*w.environment.tilt_and_rate(t), w.environment.vibration_velocity(t),
                    w.environment.vibration_accel(t)]
            vals += [g.noise_angle(t) for g in w.isu.gyros]
            vals += [a.noise.value(t) for a in w.isu.accels]
            vals += [np.array([w.oscillator.phase(float(x)) for x in t])]
            w.env.run(until=int(t[-1] * 1e9))
            vals += [np.array([w.gyro_phase(k, float(t[-1])) for k in range(3)])]
            vals += [np.array([w.string_phase(k, s, float(t[-1])) for k in range(3)
                               for s in (1, 2)])]
    elif lab == "CIGTF":
        with CigtfRack(seed, params) as cigtf:
            c = cigtf.world
            c.power_on()
            c.env.run(until=int(t[-1] * 1e9))
            vals = [np.array([c.gyro.current(float(x)) for x in t]),
                    np.array([c.average_current_ma(0.0, float(t[-1])), c.truth_theta_arcsec()])]
    else:
        with EsgRack(seed, params) as esg:
            e = esg.world
            e.spin_up()
            e.env.run(until=int(t[-1] * 1e9))
            vals = [np.array([e.rotor.spin_rps(float(x)) for x in t]),
                    np.array([e.spin_axis_lab(float(x)) for x in t]),
                    e.true_colatitudes(float(t[-1]))]
    for v in vals:
        assert np.all(np.isfinite(np.asarray(v, dtype=float))), (lab, v)


def outcome(lab: str, raw: bytes, path: Path, seed: int = 1, run_noise: bool = True
            ) -> tuple[str, str]:
    """("rejected" | "accepted", detail) for one document; a problem raises
    AssertionError; any other exception escapes (a traceback)."""
    path.write_bytes(raw)
    try:
        params = LOADERS[lab](path)
    except ConfigError as e:
        problem = message_problem(str(e), path, lab)
        assert problem is None, f"{problem}: {e}"
        return "rejected", str(e)
    if run_noise:
        exercise(lab, params, seed)
    return "accepted", ""


def as_dict(params: Any) -> dict[str, Any]:
    """Accepted params as plain data (for reports)."""
    return params.model_dump() if hasattr(params, "model_dump") else asdict(params)
