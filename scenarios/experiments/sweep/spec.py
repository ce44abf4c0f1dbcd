"""A sweep's definition: the TOML file of ``pinn-mpc sweep --spec`` and the comma-separated
lists and ranges of names and whole numbers the command line gives."""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

from pinn_mpc.choices import MODEL_CHOICES
from pinn_mpc.errors import InputError

__all__ = ["SPEC_KEYS", "parse_ints", "parse_names", "read_sweep_spec"]


def parse_names(text: str, what: str) -> tuple[str, ...]:
    """``"a,b"`` -> ("a", "b"), duplicates dropped; empty -> InputError."""
    names = tuple(dict.fromkeys(n.strip() for n in text.split(",") if n.strip()))
    if not names:
        raise InputError(f"sweep: no {what} given in {text!r}; give a comma-separated list")
    return names


#: Keys of a sweep definition file (``pinn-mpc sweep --spec FILE.toml``).
SPEC_KEYS = ("description", "scenarios", "controllers", "seeds", "train_days", "days", "baseline", "arch",
             "archs", "test_periods", "price_scenarios", "start_days")


def read_sweep_spec(path: str | os.PathLike[str]) -> dict[str, Any]:
    """A sweep definition (TOML): lists or comma-separated strings for ``scenarios``,
    ``controllers``, ``seeds`` and ``train_days`` (ranges as ``"0-7"``), ``archs`` (cem over
    each), and BOPTEST's ``test_periods`` and ``price_scenarios``; an integer ``days``, a
    controller name ``baseline``, an architecture ``arch``, the whole number ``start_days`` (the
    days of data a controller run online starts from); scenario files named relative to the
    definition file.
    Returns the values as the command line gives them."""
    import tomllib

    source = Path(path)
    if not source.is_file():
        raise InputError(f"{source}: no such sweep definition; see sweeps/ for examples")
    try:
        data = tomllib.loads(source.read_text(encoding="utf-8-sig"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{source}: not a valid TOML file ({exc})") from exc
    unknown = sorted(set(data) - set(SPEC_KEYS))
    if unknown:
        raise InputError(f"{source}: unknown key(s) {', '.join(unknown)}; known: {', '.join(SPEC_KEYS)}")
    out: dict[str, Any] = {}
    for key in ("scenarios", "controllers", "seeds", "train_days", "archs", "test_periods", "price_scenarios"):
        if key not in data:
            continue
        value = data[key]
        items = value if isinstance(value, list) else [value]
        if not all(isinstance(v, str | int) and not isinstance(v, bool) for v in items):
            raise InputError(f"{source}: {key} must be a list of names or numbers, or a string")
        if key == "scenarios":  # a scenario file is relative to the definition
            items = [
                str(source.parent / v) if isinstance(v, str) and v.endswith(".toml") else v
                for v in items
            ]
        out[key] = ",".join(str(v) for v in items)
    if "days" in data:
        if isinstance(data["days"], bool) or not isinstance(data["days"], int) or data["days"] < 1:
            raise InputError(f"{source}: days must be a whole number >= 1, got {data['days']!r}")
        out["days"] = data["days"]
    if "start_days" in data:
        value = data["start_days"]
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise InputError(f"{source}: start_days must be a whole number >= 0, got {value!r}")
        out["start_days"] = value
    if "baseline" in data:
        if not isinstance(data["baseline"], str):
            raise InputError(f"{source}: baseline must be a controller name, got {data['baseline']!r}")
        out["baseline"] = data["baseline"]
    if "arch" in data:
        if data["arch"] not in MODEL_CHOICES:
            raise InputError(f"{source}: arch must be one of {', '.join(MODEL_CHOICES)}, got {data['arch']!r}")
        out["arch"] = data["arch"]
    return out


def parse_ints(text: str, what: str) -> tuple[int, ...]:
    """``"0-7"``, ``"0,3,5"`` or ``"0-3,8"`` -> sorted whole numbers >= 0; an empty range
    (``"5-2"``) or nothing at all is an InputError."""
    values: set[int] = set()
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        match = re.fullmatch(r"(\d+)(?:-(\d+))?", part)
        if match is None:
            raise InputError(
                f"sweep: {what} {part!r} is not a whole number >= 0 or a range like 0-7"
            )
        first = int(match.group(1))
        last = int(match.group(2)) if match.group(2) is not None else first
        if last < first:
            raise InputError(f"sweep: {what} range {part!r} is empty; write it low-high, e.g. 0-7")
        values.update(range(first, last + 1))
    if not values:
        raise InputError(f"sweep: no {what} given in {text!r}; write e.g. 0-7 or 0,3,5")
    return tuple(sorted(values))


