"""Reading a laboratory's TOML configuration file: every mistake is a one-line ConfigError.

One reader serves the three laboratories (ISU, CIGTF, ESG). It refuses what is not a small
UTF-8 TOML file, a document nested deeper than any configuration is, and a top-level name
that no laboratory knows or that belongs to another laboratory's file (a file holds one
laboratory's sections, so nothing in it is silently ignored). Pydantic's validation
errors become one line naming the file and each field.
"""

from __future__ import annotations

import difflib
import os
import re
import stat
import tomllib
from collections.abc import Iterable, Mapping
from pathlib import Path
from types import UnionType
from typing import Annotated, Any, TypeVar, Union, get_args, get_origin

from pydantic import BaseModel, ValidationError

from station.errors import UseError

MAX_BYTES = 1 << 20  # the largest configuration is a few kB; anything near a MiB is not one
MAX_DEPTH = 8  # the deepest real field is four levels down (isu.gyros.0.misalignment_arcsec)
MAX_ERRORS = 4  # field errors spelt out in one message; the rest are counted

# The top-level names of each laboratory's file, and the commands that read it.
LABORATORIES: dict[str, tuple[str, ...]] = {
    "ISU": ("seed", "site", "environment", "table", "isu", "oscillator", "instruments",
            "links", "identity", "faults", "limits", "alignment", "plan", "calibration"),
    "CIGTF": ("identity", "cigtf"),  # [identity] is every laboratory's; its own one last
    "ESG": ("identity", "esg"),
}
COMMANDS = {
    "ISU": "station day, align, plan, check, serve --station isu",
    "CIGTF": "station gyrocompass-test, serve --station cigtf",
    "ESG": "station esg-calibration, serve --station esg",
}

M = TypeVar("M", bound=BaseModel)
_PLAIN = re.compile(r"[A-Za-z0-9_-]+")


class ConfigError(UseError, ValueError):
    """A configuration that cannot be used; one line naming the file and the field (exit 2;
    still a ValueError for the callers that catch one)."""


def name(part: object) -> str:
    """A key as the message shows it: bare if plain, else quoted (no newline can leak)."""
    s = str(part)
    return s if _PLAIN.fullmatch(s) else repr(s)


def dotted(parts: Iterable[object]) -> str:
    return ".".join(name(p) for p in parts)


def read_document(path: str | Path) -> dict[str, Any]:
    """The TOML document in ``path``; a ConfigError naming the file for anything else."""
    where = str(path)
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise ConfigError(f"configuration file not found: {where}") from None
    except PermissionError:
        raise ConfigError(f"{where}: cannot be read (permission denied)") from None
    except (OSError, ValueError) as e:  # a name too long, a NUL byte, a loop of links
        raise ConfigError(f"{where}: not a usable path ({_reason(e)})") from None
    if stat.S_ISDIR(info.st_mode):
        raise ConfigError(f"{where} is a directory, not a configuration file")
    if not stat.S_ISREG(info.st_mode):
        raise ConfigError(f"{where} is not a regular file (a device, pipe or socket)")
    if info.st_size > MAX_BYTES:
        raise ConfigError(f"{where}: {info.st_size} bytes is too large for a configuration "
                          f"file (at most {MAX_BYTES})")
    try:
        with open(path, "rb") as f:
            raw = f.read(MAX_BYTES + 1)
    except PermissionError:
        raise ConfigError(f"{where}: cannot be read (permission denied)") from None
    except OSError as e:
        raise ConfigError(f"{where}: cannot be read ({_reason(e)})") from None
    if len(raw) > MAX_BYTES:
        raise ConfigError(f"{where}: too large for a configuration file (over {MAX_BYTES} "
                          "bytes)")
    return parse_document(raw, where)


def parse_document(raw: bytes, where: str) -> dict[str, Any]:
    """TOML bytes to a document, refusing bad encoding, bad syntax and deep nesting."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        line = raw[: e.start].count(b"\n") + 1
        raise ConfigError(f"{where}: not UTF-8 text (byte 0x{raw[e.start]:02x} on line "
                          f"{line}); a TOML file is UTF-8") from None
    text = text.removeprefix("\ufeff")  # a byte-order mark some editors write
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{where} is not valid TOML: {_one_line(str(e))}") from None
    except RecursionError:
        raise ConfigError(f"{where}: nested too deeply to be a configuration (at most "
                          f"{MAX_DEPTH} levels)") from None
    check_depth(doc, where)
    return doc


def check_depth(doc: Mapping[str, Any], where: str) -> None:
    """Refuse a document nested deeper than MAX_DEPTH (walked without recursion)."""
    stack: list[tuple[Any, tuple[object, ...]]] = [(doc, ())]
    while stack:
        node, at = stack.pop()
        if len(at) > MAX_DEPTH:
            raise ConfigError(f"{where}: {dotted(at[:MAX_DEPTH])}... is nested more than "
                              f"{MAX_DEPTH} levels deep; no configuration field is")
        if isinstance(node, Mapping):
            stack.extend((v, (*at, k)) for k, v in node.items())
        elif isinstance(node, list | tuple):
            stack.extend((v, (*at, i)) for i, v in enumerate(node))


def check_sections(doc: Mapping[str, Any], where: str, lab: str) -> None:
    """Every top-level name must belong to ``lab``'s file; say whose it is otherwise."""
    own = LABORATORIES[lab]
    for key in doc:
        if key in own:
            continue
        owner = next((k for k, names in LABORATORIES.items() if key in names), None)
        if owner is not None:
            raise ConfigError(
                f"{where}: {name(key)} belongs to the {owner} laboratory's configuration "
                f"({COMMANDS[owner]}); the {lab} laboratory's file holds only "
                f"{_listing(own)}")
        known = [n for names in LABORATORIES.values() for n in names]
        close = difflib.get_close_matches(str(key), known, n=1, cutoff=0.6)
        hint = f" (did you mean {close[0]}?)" if close else ""
        raise ConfigError(f"{where}: unknown section or field {name(key)}{hint}; the {lab} "
                          f"laboratory's file holds only {_listing(own)}")


def validate(model: type[M], data: Any, where: str, what: str, prefix: tuple = ()) -> M:
    """``model`` from ``data``, or a one-line ConfigError naming the file and each field."""
    try:
        return model.model_validate(_without_negative_zero(data))
    except ValidationError as e:
        raise ConfigError(describe(e, where, what, prefix, model)) from None
    except RecursionError:  # only a document that escaped check_depth could get here
        raise ConfigError(f"{where}: nested too deeply to be a configuration") from None


def _without_negative_zero(data: Any) -> Any:
    """The data with every -0.0 made 0.0: the same number to a bound (-0.0 >= 0), but
    numpy refuses it as a standard deviation ("scale < 0")."""
    if isinstance(data, float) and data == 0.0:
        return 0.0
    if isinstance(data, Mapping):
        return {k: _without_negative_zero(v) for k, v in data.items()}
    if isinstance(data, list | tuple):
        return type(data)(_without_negative_zero(v) for v in data)
    return data


def describe(e: ValidationError, where: str, what: str, prefix: tuple = (),
             model: type[BaseModel] | None = None) -> str:
    """``invalid <what> configuration in <file>: a.b: msg (got x); c: msg``."""
    parts = []
    rank = {"extra_forbidden": 0, "missing": 2}  # a misspelt field first, its absence last
    errors = sorted(e.errors(), key=lambda err: rank.get(err["type"], 1))
    for err in errors[:MAX_ERRORS]:
        loc = [p for p in (*prefix, *err["loc"]) if p != "[key]"]
        msg = _one_line(err["msg"].removeprefix("Value error, "))
        if err["type"] == "extra_forbidden":
            msg = "unknown field" + _suggestion(model, err["loc"])
        elif err["type"] == "missing":
            msg = "missing (required)"
        elif _shown(err.get("input")):
            msg += f" (got {_short(err['input'])})"
        parts.append(f"{dotted(loc)}: {msg}" if loc else msg)
    if len(errors) > MAX_ERRORS:
        parts.append(f"and {len(errors) - MAX_ERRORS} more")
    return f"invalid {what} configuration in {where}: " + "; ".join(parts)


def read_section(path: str | Path, section: str, model: type[M], what: str) -> M:
    """The ``[section]`` of a one-section laboratory's file (CIGTF, ESG), validated by
    ``model``; a file without the section gives the model's defaults."""
    where = str(path)
    doc = read_document(path)
    lab = next(k for k, names in LABORATORIES.items() if names[-1] == section)
    check_sections(doc, where, lab)
    return validate(model, doc.get(section, {}), where, what, (section,))


def _suggestion(model: type[BaseModel] | None, loc: tuple) -> str:
    """`` (did you mean x?)`` for an unknown field, from the fields of the model that
    holds it; empty when nothing is close."""
    holder = _model_at(model, loc[:-1]) if model is not None else None
    if holder is None or not loc:
        return ""
    word, fields = str(loc[-1]), list(holder.model_fields)
    close = difflib.get_close_matches(word, fields, n=1, cutoff=0.6)
    close = close or [f for f in fields if f.startswith(word + "_")][:1]  # a unit left off
    return f" (did you mean {close[0]}?)" if close else ""


def _model_at(model: type[BaseModel], loc: tuple) -> type[BaseModel] | None:
    """The model class whose fields sit at ``loc`` below ``model`` (an array index or a
    mapping key after a container field passes through), or None."""
    current: Any = model
    i = 0
    while i < len(loc):
        if not (isinstance(current, type) and issubclass(current, BaseModel)):
            return None
        field = current.model_fields.get(str(loc[i]))
        if field is None:
            return None
        tp = _bare(field.annotation)
        i += 1
        while get_origin(tp) in (dict, tuple, list) and i < len(loc):
            args = get_args(tp)
            tp = _bare(args[-1] if get_origin(tp) is dict else args[0])
            i += 1
        current = tp
    return current if isinstance(current, type) and issubclass(current, BaseModel) else None


def _bare(tp: Any) -> Any:
    """An annotation without Annotated and without None in an Optional."""
    while True:
        if get_origin(tp) is Annotated:
            tp = get_args(tp)[0]
        elif get_origin(tp) in (Union, UnionType):
            rest = [a for a in get_args(tp) if a is not type(None)]
            if len(rest) != 1:
                return tp
            tp = rest[0]
        else:
            return tp


def _listing(names: tuple[str, ...]) -> str:
    return ", ".join(names)


def _shown(value: object) -> bool:
    return isinstance(value, int | float | str | bool)


def _short(value: object, n: int = 40) -> str:
    s = repr(value)
    return s if len(s) <= n else s[: n - 3] + "..."


def _one_line(s: str) -> str:
    return " ".join(s.split())


def _reason(e: BaseException) -> str:
    return _one_line(getattr(e, "strerror", None) or str(e))
