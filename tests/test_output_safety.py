"""An output held by one run at a time; a command's files written together or not at all; a
full disk named by the file it could not write (issue 33)."""

from __future__ import annotations

import errno
import json
import os
import pathlib
import subprocess
import sys
from pathlib import Path

import pytest

from pinn_mpc.data import read_fleet_params, write_timeseries
from pinn_mpc.io import atomic_write_text, written_together
from pinn_mpc_cli.cli import main
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
            "--json", str(tmp_path / "k.json"), "--csv", str(tmp_path / "traj.csv")]


def test_a_full_disk_on_the_last_file_leaves_every_file_as_it_was(tmp_path, capsys, monkeypatch):
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


def test_a_fleet_file_that_cannot_be_written_leaves_the_fleet_data_as_it_was(tmp_path, capsys, monkeypatch):
    """simulate --buildings N writes the CSV and its parameters file: when the second cannot be
    written, the first must not be replaced either (before, the new CSV stood beside the old
    parameters file, whose checksum then refused it)."""
    data, sidecar = tmp_path / "fleet.csv", tmp_path / "fleet.fleet.json"
    data.write_text("old data")
    sidecar.write_text("old parameters")
    args = ["simulate", "--scenario", "winter_household", "--buildings", "2", "--spread", "0.2",
            "--days", "1", "--seed", "0", "--out", str(data)]
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
