"""EnergyPlus's engine and files: whether it is installed, the reference buildings and weather
files it ships, a name or path resolved to a file, the calendar year a weather file's weekdays
match, and the first severe message of a run's error file.

The engine is ``pyenergyplus-lbnl`` (EnergyPlus and its API as one wheel, Linux x86_64), which
also ships DOE's reference buildings (:func:`bundled_buildings`) and TMY3 weather files
(:func:`bundled_weather`); it is imported only when a model is prepared or run.
"""

from __future__ import annotations

import re
from pathlib import Path

from pinn_mpc.errors import InputError

__all__ = [
    "WEEKDAYS",
    "bundled_buildings",
    "bundled_weather",
    "energyplus_available",
    "first_severe",
    "require_energyplus",
    "resolve_building",
    "resolve_weather",
    "weather_year",
]

#: Calendar years (not leap years) whose 1 January falls on each weekday, Monday first.
_YEAR_BY_WEEKDAY = {0: 2018, 1: 2019, 2: 2014, 3: 2015, 4: 2010, 5: 2011, 6: 2017}
WEEKDAYS = ("monday", "tuesday", "wednesday", "thursday", "friday", "saturday", "sunday")


def energyplus_available() -> bool:
    """True when the EnergyPlus engine (``pyenergyplus-lbnl``) can be imported."""
    try:
        import pyenergyplus.api  # noqa: F401
    except Exception:  # not installed, or no wheel for this platform
        return False
    return True


def require_energyplus() -> None:
    """InputError, saying how to install it, when EnergyPlus cannot be imported."""
    if not energyplus_available():
        raise InputError(
            "EnergyPlus is not installed: `pip install pyenergyplus-lbnl` (a wheel exists for "
            "Linux x86_64 only)"
        )


def bundled_buildings() -> dict[str, str]:
    """DOE reference buildings shipped with pyenergyplus: name -> IDF path (empty without it)."""
    if not energyplus_available():
        return {}
    from pyenergyplus.dataset import ref_models

    return dict(ref_models)


def bundled_weather() -> dict[str, str]:
    """TMY3 EPW files shipped with pyenergyplus: name -> path (empty without it)."""
    if not energyplus_available():
        return {}
    from pyenergyplus.dataset import weather_files

    return dict(weather_files)


def resolve_weather(name_or_path: str) -> Path:
    """An EPW file: a bundled name (``usa_il_chicago``) or a path to an ``.epw`` file."""
    bundled = bundled_weather()
    if name_or_path in bundled:
        return Path(bundled[name_or_path])
    path = Path(name_or_path)
    if path.suffix.lower() != ".epw" or not path.is_file():
        names = ", ".join(sorted(bundled)) or "none: EnergyPlus is not installed"
        raise InputError(
            f"EnergyPlus weather {name_or_path!r} is neither a bundled weather file ({names}) "
            "nor an existing .epw file"
        )
    return path


def resolve_building(name_or_path: str) -> Path:
    """A building model: a bundled reference building's name (``small_office``) or a path to an
    ``.idf`` or ``.epJSON`` file."""
    bundled = bundled_buildings()
    if name_or_path in bundled:
        return Path(bundled[name_or_path])
    path = Path(name_or_path)
    if path.suffix.lower() not in (".idf", ".epjson") or not path.is_file():
        names = ", ".join(sorted(bundled)) or "none: EnergyPlus is not installed"
        raise InputError(
            f"EnergyPlus building {name_or_path!r} is neither a bundled reference building "
            f"({names}) nor an existing .idf or .epJSON file"
        )
    return path


def weather_year(epw: Path) -> int:
    """A calendar year (not a leap year) whose weekdays match the EPW's data period."""
    try:
        with open(epw, encoding="latin-1") as f:
            header = [next(f) for _ in range(8)]
    except (OSError, StopIteration):
        raise InputError(f"{epw}: not a readable EPW weather file (no 8-line header)") from None
    line = next((h for h in header if h.upper().startswith("DATA PERIODS")), "")
    fields = [s.strip().lower() for s in line.split(",")]
    weekday = next((w for w in fields if w in WEEKDAYS), "sunday")
    return _YEAR_BY_WEEKDAY[WEEKDAYS.index(weekday)]



def first_severe(err_file: Path) -> str | None:
    """EnergyPlus's first severe (or fatal) message with its continuation lines, one line."""
    try:
        lines = err_file.read_text(errors="replace").splitlines()
    except OSError:
        return None
    for i, line in enumerate(lines):
        if "** Severe  **" in line or "**  Fatal  **" in line:
            parts = [line.split("**", 2)[-1].strip()]
            for more in lines[i + 1 :]:
                if "**   ~~~   **" not in more:
                    break
                parts.append(more.split("**", 2)[-1].strip())
            return re.sub(r"\s+", " ", " ".join(parts))
    return None
