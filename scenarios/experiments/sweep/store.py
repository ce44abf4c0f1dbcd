"""What a sweep keeps in its directory: ``sweep.json`` (its settings), the cell records and
the fitted models, each checked when read back."""

from __future__ import annotations

import dataclasses
import json
import subprocess
from pathlib import Path
from typing import Any, TypedDict, cast

from pinn_mpc import __version__
from pinn_mpc.errors import InputError, setting
from pinn_mpc.io import atomic_write_json, setting_changes
from pinn_mpc.physics import RCParams, params_from_summary, rc_summary
from scenarios.experiments.sweep.grid import RC_KIND, Cell, ModelKey, SweepSettings, scenario_digest
from scenarios.experiments.sweep.models import SweepModel
from scenarios.inputs.registry import is_scenario_file
from scenarios.plants.boptest import BUILTIN_BOPTEST
from scenarios.records import CellKey, CellRecord, SweepSettingsRecord

__all__: list[str] = []  # the sweep's storage is private to it


def _settings_record(settings: SweepSettings) -> SweepSettingsRecord:
    record = {**dataclasses.asdict(settings), "package_version": __version__}
    return cast(SweepSettingsRecord, record)  # SweepSettings' fields, then two


#: The package's checkout, whose commit a cell's record names (:func:`code_revision`).
_CHECKOUT = Path(__file__).resolve().parents[3]
#: What a cell's results depend on: an uncommitted change here is stated with the commit.
_CODE = ("pinn_mpc", "pinn_mpc_cli", "controllers", "scenarios")


def code_revision(paths: tuple[str, ...] = _CODE) -> str | None:
    """The commit of the package's git checkout that runs this sweep (12 hex digits), with
    ``+ uncommitted changes`` when what it holds under ``paths`` (by default the code) differs
    from it; None where the package is not a git checkout (installed from a wheel) or git does
    not answer within 10 s."""
    def git(*args: str) -> str | None:
        try:
            return subprocess.run(
                ["git", *args], cwd=_CHECKOUT, capture_output=True, text=True, check=True, timeout=10
            ).stdout.strip()
        except (OSError, subprocess.SubprocessError):
            return None

    if not (_CHECKOUT / ".git").exists():
        return None
    head = git("rev-parse", "--short=12", "HEAD")
    if head is None:
        return None
    dirty = git("status", "--porcelain", "--untracked-files=no", "--", *paths)
    return head + (" + uncommitted changes" if dirty else "")


def _read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(
            f"{path}: not valid JSON ({exc}); it was not written by pinn-mpc sweep "
            "(whose writes are atomic): move it away and rerun"
        ) from exc


def _check_settings(out: Path, settings: SweepSettings) -> None:
    """Refuse a rerun in ``out`` with other settings than its ``sweep.json``."""
    path = out / "sweep.json"
    record = _settings_record(settings)
    if not path.exists():
        return
    stored = _read_json(path)
    before = stored.get("settings") if isinstance(stored, dict) else None
    before = before if isinstance(before, dict) else {}
    if before != record:
        diff = setting_changes(before, record)
        raise InputError(
            f"sweep: {out} holds a sweep with other settings ({diff}); "
            f"use another {setting('out')}, or the same settings to extend it"
        )


class _CellRecordKey(TypedDict):
    cell: CellKey
    scenario_sha256: str | None


def _cell_record_key(cell: Cell) -> _CellRecordKey:
    """What identifies a cell in its record: its fields (BOPTEST's test period and price only
    on BOPTEST) and its scenario's content digest."""
    digest = (
        scenario_digest(cell.scenario)
        if is_scenario_file(cell.scenario) and cell.scenario not in BUILTIN_BOPTEST
        else None
    )
    fields = dataclasses.asdict(cell)
    if cell.test_period is None:
        del fields["test_period"], fields["price_scenario"]
    return {"cell": cast(CellKey, fields), "scenario_sha256": digest}


def _read_cell(path: Path, cell: Cell) -> CellRecord | None:
    if not path.exists():
        return None
    record = _read_json(path)
    key = _cell_record_key(cell)
    if not isinstance(record, dict) or any(record.get(k) != v for k, v in key.items()):
        raise InputError(f"{path}: not the record of cell {cell.name}; move it away and rerun")
    return cast(CellRecord, record)  # written by this module


def _model_path(out: Path, key: ModelKey) -> Path:
    suffix = ".json" if key.kind == RC_KIND else ""
    return out / "models" / f"{key.name}{suffix}"


def _load_model(out: Path, key: ModelKey) -> SweepModel | None:
    path = _model_path(out, key)
    if not path.exists():
        return None
    if key.kind == RC_KIND:
        data = _read_json(path)
        if isinstance(data, dict) and "zones" in data:  # a building of several zones
            from pinn_mpc.identify_multizone import MultiZoneIdentifyResult

            return MultiZoneIdentifyResult.from_json(data, source=str(path))
        return params_from_summary(data)
    from pinn_mpc.fitted import load

    return load(path)


def _store_model(out: Path, key: ModelKey, model: SweepModel) -> None:
    path = _model_path(out, key)
    if isinstance(model, RCParams):
        atomic_write_json(path, rc_summary(model, source=f"identify ({key.name})"))
        return
    from pinn_mpc.identify_multizone import MultiZoneIdentifyResult

    if isinstance(model, MultiZoneIdentifyResult):
        atomic_write_json(path, {**model.to_json(), "source": f"identify ({key.name})"})
        return
    from pinn_mpc.fitted import save

    save(model, path)


def _check_out(root: Path, *, force: bool) -> None:
    """Refuse an ``--out`` that is a file, or a directory of something else than a sweep
    (unless ``force``)."""
    if root.exists() and not root.is_dir():
        raise InputError(f"sweep: {setting('out')} {root} is a file; give a directory")
    if root.is_dir() and not force and not (root / "sweep.json").is_file():
        foreign = sorted(p.name + ("/" if p.is_dir() else "") for p in root.iterdir())
        if foreign:
            shown = ", ".join(foreign[:5]) + (", ..." if len(foreign) > 5 else "")
            raise InputError(
                f"sweep: {setting('out')} {root} already holds {shown} and is not a sweep directory (no "
                f"sweep.json); give a new or empty directory, or add {setting('force')} to write the sweep's "
                "files there (nothing else in it is touched)"
            )


