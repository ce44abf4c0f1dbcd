"""An output held by one run at a time; a command's files written together or not at all; a
full disk named by the file it could not write (issue 33); an existing output file replaced
only with --force."""

from __future__ import annotations

import errno
import json
import os
import pathlib
import subprocess
import sys
from pathlib import Path

import pytest

from pinn_mpc.data import (
    read_fleet_params,
    read_fleet_timeseries,
    read_timeseries,
    write_timeseries,
)
from pinn_mpc.errors import InputError
from pinn_mpc.io import atomic_write_text, check_new_files, written_together
from pinn_mpc_cli.cli import main
from scenarios.inputs.scenario_file import get_scenario, load_scenario_file
from tests.model_data import household_data

HOLD = """
import sys, time
from pinn_mpc.io import output_lock
with output_lock(sys.argv[1]):
    print("held", flush=True)
    time.sleep(120)
"""


def _holder(path: Path) -> subprocess.Popen[str]:
    """Another process holding ``path``'s lock (it says so once it does)."""
    proc = subprocess.Popen([sys.executable, "-c", HOLD, str(path)], stdout=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(Path(__file__).parents[1])})
    assert proc.stdout is not None and proc.stdout.readline().strip() == "held"
    return proc


def _commands(tmp_path: Path) -> dict[str, tuple[list[str], Path]]:
    """Each command writing an output directory (or compare's report), and what it holds."""
    data = tmp_path / "d.csv"
    write_timeseries(household_data(6, 0), data)
    out = tmp_path / "out"
    return {
        "train": (["train", "--data", str(data), "--arch", "parx", "--out", str(out)], out),
        "train-per-building": (["train", "--data", str(data), "--per-building", "--out", str(out)], out),
        "sweep": (["sweep", "--scenarios", "winter_household", "--controllers", "thermostat",
                   "--seeds", "0", "--days", "1", "--out", str(out)], out),
        "reproduce": (["reproduce", "--quick", "--out", str(out)], out),
        "compare": (["compare", "--scenario", "winter_household", "--quick", "--json",
                     str(tmp_path / "c.json"), "--report", str(tmp_path / "r.md")], tmp_path / "r.md"),
    }


@pytest.mark.parametrize("command", ["train", "train-per-building", "sweep", "reproduce", "compare"])
def test_a_second_run_into_a_held_output_is_refused_in_one_line(tmp_path, capsys, command):
    args, held = _commands(tmp_path)[command]
    proc = _holder(held)
    try:
        before = sorted(p.name for p in tmp_path.iterdir())
        assert main(args) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1, err
        assert f"is being written by another run (pid {proc.pid}" in err
        assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written
    finally:
        proc.kill()
        proc.wait()


def test_the_lock_of_a_dead_run_is_taken_over_and_released_at_the_end(tmp_path, capsys):
    args, held = _commands(tmp_path)["train"]
    proc = _holder(held)
    proc.kill()  # killed: its lock file stays, with its pid
    proc.wait()
    lock = tmp_path / ".out.lock"
    assert lock.read_text().strip() == str(proc.pid)
    assert main(args) == 0, capsys.readouterr().err
    assert not lock.exists() and (held / "arx.json").is_file()


def _loop(tmp_path: Path) -> list[str]:
    return ["closed-loop", "--scenario", "winter_household", "--controller", "thermostat", "--days", "1",
            "--json", str(tmp_path / "k.json"), "--csv", str(tmp_path / "traj.csv"), "--force"]


def test_a_full_disk_on_the_last_file_leaves_every_file_as_it_was(tmp_path, capsys, monkeypatch) -> None:
    """closed-loop --json --csv: the KPI JSON cannot be written (no space left); the CSV
    written before it must not replace the old one, and the message names k.json."""
    (tmp_path / "k.json").write_text("old kpis")
    (tmp_path / "traj.csv").write_text("old trajectory")
    write_text = pathlib.Path.write_text

    def full(self: Path, *args: object, **kwargs: object) -> int:
        if self.name.startswith(".k.json."):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return write_text(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(pathlib.Path, "write_text", full)
    assert main(_loop(tmp_path)) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith(f"No space left on device ({tmp_path / 'k.json'})"), err
    assert (tmp_path / "k.json").read_text() == "old kpis"
    assert (tmp_path / "traj.csv").read_text() == "old trajectory"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["k.json", "traj.csv"]  # no temporaries
    monkeypatch.undo()
    assert main(_loop(tmp_path)) == 0
    assert json.loads((tmp_path / "k.json").read_text())["days"] == 1


def test_a_fleet_file_that_cannot_be_written_leaves_the_fleet_data_as_it_was(tmp_path, capsys, monkeypatch) -> None:
    """simulate --buildings N writes the CSV and its parameters file: when the second cannot be
    written, the first must not be replaced either (before, the new CSV stood beside the old
    parameters file, whose checksum then refused it)."""
    data, sidecar = tmp_path / "fleet.csv", tmp_path / "fleet.fleet.json"
    data.write_text("old data")
    sidecar.write_text("old parameters")
    args = ["simulate", "--scenario", "winter_household", "--buildings", "2", "--spread", "0.2",
            "--days", "1", "--seed", "0", "--out", str(data), "--force"]
    write_text = pathlib.Path.write_text

    def full(self: Path, *a: object, **kw: object) -> int:
        if self.name.startswith(".fleet.fleet.json."):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return write_text(self, *a, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(pathlib.Path, "write_text", full)
    assert main(args) == 2
    assert capsys.readouterr().err.strip().endswith(f"No space left on device ({sidecar})")
    assert data.read_text() == "old data" and sidecar.read_text() == "old parameters"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fleet.csv", "fleet.fleet.json"]
    monkeypatch.undo()
    assert main(args) == 0
    assert len(read_fleet_params(data, 2) or []) == 2  # the checksum is the CSV's written


def test_a_real_full_file_system(tmp_path, capsys):
    """The same on a tiny tmpfs (root only) with room for the trajectory CSV alone: before,
    the CSV was replaced and the JSON not."""
    disk = tmp_path / "disk"
    disk.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(disk)],
                      capture_output=True).returncode != 0:
        pytest.skip("mounting a tmpfs needs root")
    try:
        assert main(_loop(tmp_path)) == 0  # the sizes the files take
        csv_bytes = (tmp_path / "traj.csv").stat().st_size
        (disk / "k.json").touch()
        (disk / "traj.csv").touch()
        stat = os.statvfs(disk)
        block = stat.f_frsize
        room = -(-csv_bytes // block) * block  # the CSV fits, nothing after it
        (disk / "fill").write_bytes(b"\0" * (stat.f_bavail * block - room))
        assert os.statvfs(disk).f_bavail * block == room
        capsys.readouterr()
        assert main(_loop(disk)) == 2
        assert "No space left on device" in capsys.readouterr().err
        assert (disk / "k.json").stat().st_size == 0 and (disk / "traj.csv").stat().st_size == 0
        assert sorted(p.name for p in disk.iterdir()) == ["fill", "k.json", "traj.csv"]
    finally:
        subprocess.run(["umount", str(disk)], check=False)


def test_written_together_renames_nothing_until_the_block_ends(tmp_path):
    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    with written_together():
        atomic_write_text(a, "A")
        assert not a.exists()
        atomic_write_text(b, "B")
    assert a.read_text() == "A" and b.read_text() == "B"
    with pytest.raises(RuntimeError), written_together():
        atomic_write_text(a, "new A")
        raise RuntimeError("a failure after the first file")
    assert a.read_text() == "A" and sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.txt"]


# ------------------------------------------------------- an existing file is replaced only with --force

PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Data of the paper's household and an ARX model trained on them (which carries the RC
    identified from them), in a directory of their own."""
    root = tmp_path_factory.mktemp("inputs")
    write_timeseries(household_data(6, 0), root / "d.csv")
    assert main(["train", "--data", str(root / "d.csv"), "--arch", "arx", "--out", str(root / "arx")]) == 0
    return {"data": root / "d.csv", "model": root / "arx"}


LOOP_1 = ["closed-loop", "--scenario", "winter_household", "--days", "1"]


def _writers(out: Path, inputs: dict[str, Path]) -> dict[str, tuple[list[str], list[tuple[str, Path]]]]:
    """Each command that writes files the user names: its arguments and the files it writes
    into ``out``, each with the option that names it (a file written beside another: that one's)."""
    data, model = str(inputs["data"]), str(inputs["model"])
    return {
        "simulate": (["simulate", "--scenario", "winter_household", "--days", "1", "--out", str(out / "s.csv")],
                     [("--out", out / "s.csv")]),
        "simulate-fleet": (["simulate", "--scenario", "winter_household", "--days", "1", "--buildings", "2",
                            "--out", str(out / "f.csv")],
                           [("--out", out / "f.csv"), ("--out", out / "f.fleet.json")]),
        "identify": (["identify", "--data", data, "--out", str(out / "rc.json")], [("--out", out / "rc.json")]),
        "evaluate": (["evaluate", "--model", model, "--data", data, "--json", str(out / "m.json")],
                     [("--json", out / "m.json")]),
        "export-rc": (["export-rc", "--model", model, "--out", str(out / "rc.json")], [("--out", out / "rc.json")]),
        "closed-loop": ([*LOOP_1, "--controller", "thermostat", "--json", str(out / "k.json"),
                         "--csv", str(out / "t.csv"), "--plot", str(out / "p.png")],
                        [("--json", out / "k.json"), ("--csv", out / "t.csv"), ("--plot", out / "p.png")]),
        "closed-loop-fleet": ([*LOOP_1, "--controller", "qp-mpc", "--buildings", "2", "--batched",
                               "--json", str(out / "k.json")],
                              [("--json", out / "k.json"), ("--json", out / "k.fleet.png")]),
        "scenario-export": (["scenario", "export", "winter_household", "--out", str(out / "s.toml")],
                            [("--out", out / "s.toml")]),
    }


def _tree(root: Path) -> dict[str, bytes]:
    """{path relative to ``root``: its bytes} of every file under ``root``."""
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def _is_written(path: Path) -> bool:
    """``path`` holds what its command writes (not the user's bytes): a data CSV, a JSON
    object, a PNG or a scenario file."""
    if path.suffix == ".png":
        return path.read_bytes()[:8] == PNG
    if path.suffix == ".json":
        return isinstance(json.loads(path.read_text()), dict)
    if path.suffix == ".toml":
        return load_scenario_file(path) == get_scenario("winter_household")
    frames = list(read_fleet_timeseries(path).values()) if path.name == "f.csv" else [read_timeseries(path)]
    return [len(f) for f in frames] == [48] * len(frames)  # one day of each building


CASES = [
    pytest.param(command, i, id=f"{command}-{i}")
    for command, n in (("simulate", 1), ("simulate-fleet", 2), ("identify", 1), ("evaluate", 1),
                       ("export-rc", 1), ("closed-loop", 3), ("closed-loop-fleet", 2), ("scenario-export", 1))
    for i in range(n)
]


@pytest.mark.parametrize(("command", "index"), CASES)
def test_an_existing_output_file_is_refused_before_any_work_and_replaced_only_with_force(
    tmp_path, capsys, inputs, command, index
):
    """The file ``index`` of the command's outputs exists (the user's): the command exits 2 in
    one line naming it, its option and --force, leaves it byte for byte and writes nothing
    else (the files before it not either: every output is checked before any work); with
    --force every output is written and the user's file replaced."""
    args, files = _writers(tmp_path, inputs)[command]
    option, mine = files[index]
    user_bytes = b"the user's own file, perhaps edited\n"
    mine.write_bytes(user_bytes)
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    named = next(p for o, p in files if o == option)  # the file its option names
    assert f"{mine}" in err and f"{option} {named}" in err and "already exists" in err, err
    assert err.endswith("add --force to replace it"), err
    assert _tree(tmp_path) == {mine.name: user_bytes}  # nothing else written, no temporaries
    assert main([*args, "--force"]) == 0, capsys.readouterr().err
    assert sorted(_tree(tmp_path)) == sorted(p.name for _, p in files)
    assert all(_is_written(p) for _, p in files)


def test_an_existing_output_of_an_online_run_is_refused_before_its_directory_is_made(tmp_path, capsys):
    """closed-loop --online DIR keeps its directory's semantics (--resume); its --json is a
    file as any other: an existing one is refused before DIR is made."""
    (tmp_path / "k.json").write_text("my KPIs")
    assert main([*LOOP_1, "--controller", "qp-mpc", "--online", str(tmp_path / "run"),
                 "--json", str(tmp_path / "k.json")]) == 2
    assert "--json " in capsys.readouterr().err
    assert _tree(tmp_path) == {"k.json": b"my KPIs"}


def test_the_library_names_the_settings_not_the_flags(tmp_path):
    """From Python the message names the settings (``out``, ``force``); nothing is refused
    with ``force`` or where no file exists."""
    out = tmp_path / "x.json"
    check_new_files({"out": out, "json": None}, force=False)
    out.write_text("{}")
    check_new_files({"out": out}, force=True)
    with pytest.raises(InputError) as refused:
        check_new_files({"json": None, "out": [tmp_path / "new.csv", out]}, force=False)
    assert str(refused.value) == (
        f"{out} (written beside out {tmp_path / 'new.csv'}) already exists; choose another out, or "
        "add force to replace it"
    )
    assert "--" not in str(refused.value)


def test_an_online_runs_plot_is_drawn_and_an_existing_one_refused(tmp_path, capsys):
    """closed-loop --online DIR --plot F draws the run's trajectory into F (it used to be
    ignored without a word); an existing F is refused before DIR is made, as --json is."""
    figure, run = tmp_path / "online.png", tmp_path / "run"
    figure.write_bytes(b"my figure")
    args = [*LOOP_1, "--controller", "qp-mpc", "--online", str(run), "--plot", str(figure)]
    assert main(args) == 2
    assert "--plot " in capsys.readouterr().err
    assert _tree(tmp_path) == {"online.png": b"my figure"}
    figure.unlink()
    assert main(args) == 0, capsys.readouterr().err
    assert figure.read_bytes().startswith(b"\x89PNG") and f"wrote {figure}" in capsys.readouterr().out


def test_an_online_run_on_a_zoned_building_is_refused_in_one_line(tmp_path, capsys):
    """closed-loop --online on a building of several zones stopped with an internal error (its
    refits fit one zone); it is refused in one line, as the sweep refuses such cells, before
    DIR is made."""
    run = tmp_path / "run"
    args = ["closed-loop", "--scenario", "two_zone_house", "--days", "1", "--controller", "cem", "--online", str(run)]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "'two_zone_house' has 2 zones" in err, err
    assert not run.exists()
