"""Nothing lost, nothing overwritten unasked, no tracebacks (issue 8, cases 1, 2, 6, 7, 8).

Every refusal runs the CLI's entry point (:func:`pinn_mpc_cli.cli.main`, in this process: an
import of the libraries per case would take most of the test's time) in a sandbox holding a
user's files, from the sandbox's folder, and checks: exit 2, one line on stderr naming the
problem, and the sandbox byte for byte as it was (nothing deleted, overwritten or half-written,
no temporary files left behind). The refusal that a regression would turn into a hang (an
output that is a named pipe, which opening blocks) runs the real command (``python -m
pinn_mpc``), with a timeout, as the other tests here do.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from pinn_mpc.artifacts import MODEL_DIRECTORY, load_model
from pinn_mpc.errors import InputError
from pinn_mpc.io import DirectoryLayout, atomic_directory, check_distinct
from pinn_mpc_cli.cli import MAX_DAYS, build_parser, main
from scenarios.inputs.registry import scenario_names
from scenarios.running.factory import CONTROLLER_NAMES

TINY = ["--arch", "mlp", "--seeds", "1", "--epochs", "1"]
LOOP = ["closed-loop", "--scenario", "paper_household", "--controller", "thermostat", "--days", "1"]


def run_cli(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pinn_mpc", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
    )


def snapshot(root: Path) -> dict[str, bytes | None]:
    """Every path under ``root`` with its bytes (None for a directory)."""
    return {
        str(p.relative_to(root)): (p.read_bytes() if p.is_file() else None)
        for p in sorted(root.rglob("*"))
    }


@pytest.fixture(scope="module")
def template(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A user's folder: data, a trained model, a project with a thesis, an RC file, a link."""
    root = tmp_path_factory.mktemp("user")
    argv = ["simulate", "--scenario", "paper_household", "--days", "3", "--out"]
    assert main([*argv, str(root / "d.csv")]) == 0
    assert main(["train", "--data", str(root / "d.csv"), *TINY, "--out", str(root / "m")]) == 0
    assert main(["train", "--data", str(root / "d.csv"), "--arch", "arx", "--out", str(root / "arx")]) == 0
    shutil.copy(root / "d.csv", root / "test.csv")
    (root / "link.csv").symlink_to("test.csv")
    (root / "project" / "sub").mkdir(parents=True)
    (root / "project" / "thesis.txt").write_text("four years of work\n")
    (root / "project" / "sub" / "notes.txt").write_text("notes\n")
    (root / "up" / "inner").mkdir(parents=True)
    (root / "up" / "keep.txt").write_text("keep me\n")
    shutil.copy(root / "d.csv", root / "up" / "inner" / "d.csv")
    (root / "clash" / "model.json").mkdir(parents=True)
    (root / "clash" / "model.json" / "keep.txt").write_text("not a model file\n")
    (root / "rc.json").write_text('{"R_ra_K_per_W": 0.00375}\n')
    return root


@pytest.fixture
def sandbox(template: Path, tmp_path: Path) -> Path:
    root = tmp_path / "user"
    shutil.copytree(template, root, symlinks=True)
    os.mkfifo(root / "pipe")  # not in the template: copying a pipe would block
    return root


def case(name: str, argv: list[str], *fragments: str, cwd: str = ".") -> object:
    """A refusal: run ``argv`` in ``cwd`` of the sandbox; the error line holds ``fragments``."""
    return pytest.param(cwd, argv, fragments, id=name)


TRAIN = ["train", "--data", "d.csv", *TINY]
QUICK = ["compare", "--quick", "--json"]
REFUSALS = [
    # 1. data loss: a directory output never replaces a directory of other content
    case("train-into-a-project", [*TRAIN, "--out", "project"],
         "project already holds sub/, thesis.txt", "not a model directory", "--force"),
    case("train-into-the-parent", [*TRAIN, "--out", ".."],
         "already holds inner/, keep.txt", "--force", cwd="up/inner"),
    case("train-into-the-working-directory", [*TRAIN, "--out", "."], "already holds d.csv",
         "--force", cwd="up/inner"),
    case("train-onto-a-file", [*TRAIN, "--out", "test.csv"], "test.csv", "a file of that name"),
    case("train-force-onto-a-folder-named-model-json", [*TRAIN, "--out", "clash", "--force"],
         "model.json in it is a directory"),
    case("train-out-is-empty", [*TRAIN, "--out", ""], "model directory name is empty"),
    case("reproduce-into-a-project", ["reproduce", "--quick", "--out", "project"],
         "project already holds sub/, thesis.txt", "not a reproduction directory", "--force"),
    # 2. outputs that would overwrite an input or each other
    case("identify-out-is-the-data", ["identify", "--data", "test.csv", "--out", "test.csv"],
         "--out test.csv is the same file as the input --data test.csv"),
    case("identify-out-is-the-data-via-dotdot",
         ["identify", "--data", "test.csv", "--out", "project/../test.csv"], "same file as the"),
    case("identify-out-is-a-link-to-the-data",
         ["identify", "--data", "test.csv", "--out", "link.csv"], "same file as the input --data"),
    case("train-data-inside-out", ["train", "--data", "m/model.json", *TINY, "--out", "m"],
         "--out m/model.json is the same file as the input --data"),
    case("evaluate-json-is-the-models-metadata",
         ["evaluate", "--model", "m", "--data", "d.csv", "--json", "m/model.json"],
         "same file as the input --model m/model.json"),
    case("evaluate-json-is-the-data",
         ["evaluate", "--model", "m", "--data", "d.csv", "--json", "./d.csv"], "input --data"),
    case("export-rc-out-is-the-weights",
         ["export-rc", "--model", "m", "--out", "m/weights.safetensors"], "input --model"),
    case("closed-loop-csv-is-the-json", [*LOOP, "--json", "X", "--csv", "X"],
         "--csv X and --json X are the same file"),
    case("closed-loop-plot-is-the-json", [*LOOP, "--json", "k.png", "--plot", "./k.png"],
         "are the same file"),
    case("closed-loop-json-is-the-rc",
         [*LOOP[:4], "qp-mpc", "--rc", "rc.json", "--days", "1", "--json", "rc.json"],
         "same file as the input --rc"),
    case("closed-loop-json-is-the-models-weights",
         [*LOOP[:4], "cem", "--model", "m", "--days", "1", "--json", "m/weights.safetensors"],
         "same file as the input --model"),
    case("closed-loop-json-is-the-arx-models-file",
         [*LOOP[:4], "qp-mpc", "--model", "arx", "--days", "1", "--json", "arx/arx.json"],
         "same file as the input --model"),
    case("closed-loop-on-boptest-json-is-the-arx-models-file",
         ["closed-loop", "--scenario", "boptest_hydronic_heat_pump", "--controller", "cem", "--model",
          "arx", "--test-period", "peak_heat_day", "--json", "arx/arx.json"],
         "same file as the input --model"),
    case("closed-loop-json-is-a-pipe", [*LOOP, "--json", "pipe"], "pipe: it is not a regular"),
    case("compare-report-is-its-own-figure", [*QUICK, "t.json", "--report", "out.png"],
         "--report out.png", "name ending in .md"),
    case("compare-json-is-the-figure", [*QUICK, "r.png", "--report", "r.md"],
         "r.png", "are the same file"),
    # 6. tracebacks before
    case("simulate-too-many-days",
         ["simulate", "--scenario", "paper_household", "--days", "100000", "--out", "big.csv"],
         "--days", f"more than the {MAX_DAYS}"),
    case("compare-report-is-a-directory", [*QUICK, "t.json", "--report", "."],
         "cannot write .", "directory"),
    case("compare-report-is-dotdot-of-a-missing-directory",
         [*QUICK, "t.json", "--report", "nowhere/.."], "cannot write nowhere/..", "directory"),
    # 7. messages in the user's words
    case("model-is-a-file",
         [*LOOP[:4], "cem", "--model", "test.csv", "--days", "1", "--json", "k.json"],
         "test.csv is a file, not a model directory"),
    case("lambda-infinite",
         ["train", "--data", "d.csv", "--arch", "physnet", "--lambda", "inf", "--out", "m2"],
         "--lambda", "finite"),
    case("seed-negative", [*TRAIN, "--seed", "-1", "--out", "m2"], "--seed", "-1"),
]


def run_main(
    argv: list[str], cwd: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> subprocess.CompletedProcess[str]:
    """``pinn-mpc argv`` through :func:`main` in this process, from ``cwd``: its exit status
    (argparse's own exit as well) and what it printed."""
    capsys.readouterr()
    monkeypatch.chdir(cwd)
    try:
        status = main(argv)
    except SystemExit as exc:
        status = exc.code if isinstance(exc.code, int) else 1
    out, err = capsys.readouterr()
    return subprocess.CompletedProcess(argv, status, out, err)


@pytest.mark.parametrize(("cwd", "argv", "fragments"), REFUSALS)
def test_refused_with_one_line_and_nothing_lost(
    sandbox: Path,
    cwd: str,
    argv: list[str],
    fragments: list[str],
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    before = snapshot(sandbox)
    if "pipe" in argv:
        result = run_cli(*argv, cwd=sandbox / cwd)
    else:
        result = run_main(argv, sandbox / cwd, capsys, monkeypatch)
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2, result.stderr
    assert len(lines) == 1 and lines[0].startswith(f"pinn-mpc {argv[0]}: error: "), lines
    for fragment in fragments:
        assert fragment in lines[0]
    assert "TrainConfig" not in lines[0] and result.stdout == ""
    assert snapshot(sandbox) == before


@pytest.mark.parametrize(("cwd", "out"), [(".", "project"), ("up/inner", "..")])
def test_force_replaces_only_the_models_own_files(sandbox: Path, cwd: str, out: str) -> None:
    target = (sandbox / cwd / out).resolve()
    own = {str((target / name).relative_to(sandbox)) for name in MODEL_DIRECTORY.files}
    before = snapshot(sandbox)
    result = run_cli(
        "train", "--data", str(sandbox / "d.csv"), *TINY, "--out", out, "--force", cwd=sandbox / cwd
    )
    assert result.returncode == 0, result.stderr
    after = snapshot(sandbox)
    assert set(after) - set(before) == own  # the model's two files, and no temporary leftovers
    assert {k: v for k, v in after.items() if k not in own} == before
    for name in MODEL_DIRECTORY.files:
        assert str(Path(out) / name) in result.stdout  # the summary names every file written
    assert load_model(target).n_members == 1


def test_a_model_directory_is_replaced_without_force(sandbox: Path) -> None:
    old = load_model(sandbox / "m").meta["seeds"]
    result = run_cli("train", "--data", "d.csv", *TINY, "--seed", "7", "--out", "m", cwd=sandbox)
    assert result.returncode == 0, result.stderr
    assert sorted(os.listdir(sandbox / "m")) == sorted(MODEL_DIRECTORY.files)
    assert old == [0] and load_model(sandbox / "m").meta["seeds"] == [7]


def test_closed_loop_names_every_file_and_shows_no_bar_off_a_terminal(sandbox: Path) -> None:
    result = run_cli(*LOOP, "--json", "k.json", "--csv", "k.csv", "--plot", "k.png", cwd=sandbox)
    assert result.returncode == 0 and result.stderr == ""
    assert result.stdout.splitlines()[-1] == "wrote k.json, k.csv, k.png"
    assert len(pd.read_csv(sandbox / "k.csv")) == 48


@pytest.mark.skipif(os.name != "posix", reason="pseudo-terminal")
def test_long_closed_loop_shows_progress_on_a_terminal(tmp_path: Path) -> None:
    import fcntl
    import pty
    import struct
    import termios

    # 200 days of thermostat take a few seconds, past the bar's 1 s delay
    argv = [*LOOP[:-1], "200", "--json", str(tmp_path / "k.json")]
    pid, fd = pty.fork()
    if pid == 0:  # the child: the CLI with a terminal on stdout and stderr
        os.execv(sys.executable, [sys.executable, "-m", "pinn_mpc", *argv])
    fcntl.ioctl(fd, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))
    output = b""
    while True:
        try:
            chunk = os.read(fd, 4096)
        except OSError:  # the child closed the terminal
            break
        if not chunk:
            break
        output += chunk
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0
    assert b"step/s" in output and b"wrote " in output


def _options(parser) -> dict[str, list]:
    sub = next(a for a in parser._actions if a.dest == "command")
    return {name: [a for a in p._actions if a.dest != "help"] for name, p in sub.choices.items()}


def test_every_option_has_help_and_shows_its_default(capsys: pytest.CaptureFixture[str]) -> None:
    for command, actions in _options(build_parser()).items():
        with pytest.raises(SystemExit):
            main([command, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        for action in actions:
            assert action.help, f"{command} {action.option_strings} has no help"
            has_default = not action.required and not any(
                action.default is v for v in (None, False)
            )
            # A positional (the ACTION of `scenario`) is shown by its metavar.
            shown = (action.option_strings or [action.metavar])[0] in text
            assert shown
            if has_default:
                default = action.default
                assert f"(default: {default})" in text, (command, action.option_strings)
        if any(a.dest == "scenario" for a in actions):
            assert ", ".join(scenario_names()) in text
        if command == "closed-loop":
            assert ", ".join(CONTROLLER_NAMES) in text
        if command == "simulate":  # the scenario's data policy
            assert "(default: the scenario's data_policy: random-level, closed-loop on EnergyPlus)" in text


def test_simulate_defaults_to_random_levels(tmp_path: Path) -> None:
    out = tmp_path / "d.csv"
    assert (
        main(["simulate", "--scenario", "paper_household", "--days", "2", "--out", str(out)]) == 0
    )
    demand = pd.read_csv(out)["u"]
    assert demand.nunique() == len(demand) == 96


LAYOUT = DirectoryLayout(kind="test output", files=("a.txt", "b.txt"), markers=("a.txt",))


def test_a_failed_write_into_an_existing_directory_changes_nothing(tmp_path: Path) -> None:
    (tmp_path / "a.txt").write_text("old a\n")
    (tmp_path / "mine.txt").write_text("mine\n")
    before = snapshot(tmp_path)
    with pytest.raises(OSError, match="disk full"):
        with atomic_directory(tmp_path, LAYOUT, force=True) as tmp:
            (tmp / "a.txt").write_text("new a\n")
            raise OSError("disk full")
    assert snapshot(tmp_path) == before
    with atomic_directory(tmp_path, LAYOUT, force=True) as tmp:
        (tmp / "a.txt").write_text("new a\n")
    assert (tmp_path / "a.txt").read_text() == "new a\n"
    assert snapshot(tmp_path).keys() == before.keys()  # b.txt not written, mine.txt kept


def test_a_new_directory_appears_whole_or_not_at_all(tmp_path: Path) -> None:
    target = tmp_path / "new"
    with pytest.raises(KeyboardInterrupt):
        with atomic_directory(target, LAYOUT) as tmp:
            (tmp / "a.txt").write_text("a\n")
            raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []
    with atomic_directory(target, LAYOUT) as tmp:
        (tmp / "a.txt").write_text("a\n")
        (tmp / "b.txt").write_text("b\n")
    assert sorted(os.listdir(target)) == ["a.txt", "b.txt"]


def test_a_writer_never_puts_a_foreign_file_in_place(tmp_path: Path) -> None:
    (tmp_path / "a.txt").write_text("old a\n")
    with pytest.raises(RuntimeError, match="c.txt"):
        with atomic_directory(tmp_path, LAYOUT) as tmp:
            (tmp / "a.txt").write_text("new a\n")
            (tmp / "c.txt").write_text("c\n")
    assert sorted(os.listdir(tmp_path)) == ["a.txt"]
    assert (tmp_path / "a.txt").read_text() == "old a\n"


def test_own_files_without_the_marker_are_not_the_same_kind(tmp_path: Path) -> None:
    (tmp_path / "b.txt").write_text("a user's b\n")
    with pytest.raises(InputError, match="already holds b.txt, so it is not a test output"):
        with atomic_directory(tmp_path, LAYOUT):
            pass


def test_hard_links_are_the_same_file(tmp_path: Path) -> None:
    (tmp_path / "data.csv").write_text("x\n")
    os.link(tmp_path / "data.csv", tmp_path / "alias.csv")
    with pytest.raises(InputError, match="same file as the input --data"):
        check_distinct(
            inputs={"--data": tmp_path / "data.csv"}, outputs={"--out": tmp_path / "alias.csv"}
        )
    check_distinct(inputs={"--data": tmp_path / "data.csv"}, outputs={"--out": tmp_path / "o.csv"})


def test_ctrl_c_during_an_atomic_write_finishes_the_file_then_interrupts(tmp_path: Path) -> None:
    import signal

    from pinn_mpc.io import atomic_write

    target = tmp_path / "cell.json"

    def writer(tmp: Path) -> None:
        tmp.write_text("half", encoding="utf-8")
        os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C in the middle of the write
        tmp.write_text("whole", encoding="utf-8")

    with pytest.raises(KeyboardInterrupt):
        atomic_write(target, writer)
    assert target.read_text(encoding="utf-8") == "whole"
    assert [p.name for p in tmp_path.iterdir()] == ["cell.json"]  # no temporary file left
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
