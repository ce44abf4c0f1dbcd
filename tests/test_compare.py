"""The comparison: report rendering, settings, and the ``compare`` command end to end."""

import json

import pandas as pd
import pytest

from pinn_mpc.errors import InputError
from pinn_mpc.physics import PAPER_HOUSEHOLD, rc_summary
from pinn_mpc_cli.cli import build_parser, main
from scenarios.experiments.compare import CompareSettings
from scenarios.experiments.sweep import SweepSettings
from scenarios.inputs.scenario_file import get_scenario
from scenarios.records import CompareTable
from scenarios.reports.report import format_kpis, kpi_table_text, objective_ratios, render_report
from scenarios.running.kpis import KPI_KEYS
from tests.test_records import assert_record


def _row(label, objective, **extra):
    row = {key: 0 for key in KPI_KEYS}
    return {**row, "controller": label, "objective": objective, **extra}


def test_objective_ratios_against_the_oracle():
    rows = [_row("thermostat", 3.0), _row("oracle", 2.0), _row("cem / physnet", 2.5)]
    assert objective_ratios(rows, reference="oracle") == pytest.approx([1.5, 1.0, 1.25])
    assert objective_ratios(rows[:1], reference="oracle") == [None]
    assert objective_ratios([_row("oracle", 0.0)], reference="oracle") == [None]


def test_kpi_table_text_has_a_line_per_controller():
    rows = [_row("thermostat", 3.0, objective_to_oracle=1.5), _row("oracle", 2.0)]
    lines = kpi_table_text(rows).splitlines()
    assert len(lines) == 3
    assert lines[0].startswith("controller") and "objective EUR" in lines[0]
    assert lines[1].split()[:3] == ["thermostat", "3.000", "1.500"]
    assert lines[2].split()[:3] == ["oracle", "2.000", "n/a"]


def test_kpi_tables_and_line_show_the_discomfort_as_avoidable_and_unavoidable():
    """Every KPI table names its discomfort columns; a run whose unavoidable part was not
    computed (BOPTEST) says so rather than 0."""
    split = {"discomfort_kh": 9.92, "discomfort_avoidable_kh": 1.51, "discomfort_unavoidable_kh": 8.41}
    rows = [
        _row("oracle", 2.0, **split),
        _row("boptest", 3.0, discomfort_kh=4.0, discomfort_avoidable_kh=None,
             discomfort_unavoidable_kh=None),
    ]
    lines = kpi_table_text(rows).splitlines()
    headers = [h.strip() for h in lines[0].split("  ") if h.strip()]
    at = headers.index("avoidable discomfort K h")
    assert headers[at + 1 : at + 3] == ["unavoidable discomfort K h", "total discomfort K h"]
    assert "discomfort K h" not in headers  # no column without saying which
    assert "1.510" in lines[1] and "8.410" in lines[1] and "9.920" in lines[1]
    assert lines[2].count("not computed") == 2
    text = render_report(
        scenario="winter_household", description="", rows=rows, rc={}, settings={},
        figure_name="f.png", dates="",
    )
    assert "| avoidable discomfort K h | unavoidable discomfort K h | total discomfort K h |" in text
    assert "| 1.510 | 8.410 | 9.920 |" in text and "| not computed | not computed | 4.000 |" in text
    assert "no controller of this actuator could have avoided" in text
    line = {**rows[0], "scenario": "winter_household", "days": 2}
    assert "discomfort 9.92 K h (avoidable 1.51, unavoidable 8.41)" in format_kpis(line)
    line = {**rows[1], "scenario": "boptest", "days": 2}
    assert "discomfort 4.00 K h (unavoidable not computed)" in format_kpis(line)


def test_report_lists_kpis_rc_parameters_and_figure():
    true = rc_summary(PAPER_HOUSEHOLD, source="true")
    text = render_report(
        scenario="paper_household",
        description="The paper's household.",
        rows=[_row("oracle", 2.0, objective_to_oracle=1.0)],
        rc={"true": true, "identified": true},
        settings={"train_days": 60},
        figure_name="report.png",
        dates="Training data: 60 days, 2021-04-01 to 2021-05-30.",
    )
    assert "# Closed-loop comparison on `paper_household`" in text
    assert "The paper's household.\n\nTraining data: 60 days, 2021-04-01 to 2021-05-30.\n" in text
    assert "| `oracle` | 2.000 | 1.000 |" in text
    # R_ra = 3.75e-3 K/W is 3.75 mK/W; C_r = 4e6 J/K is 4 MJ/K.
    assert "| R_ra [mK/W] | 3.75 | 3.75 |" in text
    assert "| C_r [MJ/K] | 4 | 4 |" in text
    assert "![room temperature and delivered power of every controller](report.png)" in text
    assert "| train_days | `60` |" in text


def test_quick_settings_are_small():
    quick = CompareSettings.for_run(train_days=60, days=None, seed=0, quick=True)
    full = CompareSettings.for_run(train_days=60, days=None, seed=0, quick=False)
    assert quick.test_days == 2 and full.test_days == 5
    assert quick.n_seeds < full.n_seeds and quick.cem_samples == full.cem_samples
    assert quick.test_seed != quick.seed
    assert full.policy == quick.policy == "random-level" and full.depth == 16
    # As many optimizer steps as the recipe's calibration (60 epochs of 120 days).
    assert full.training_epochs == 120 and quick.training_epochs == 60
    assert CompareSettings(train_days=10, test_days=1, seed=0).training_epochs == 240
    assert CompareSettings(train_days=365, test_days=1, seed=0).training_epochs == 60


def test_quick_honours_the_days_asked_for():
    """--quick shortens the default test, never the days given (it once capped them at 2)."""
    assert CompareSettings.for_run(train_days=60, days=5, seed=0, quick=True).test_days == 5
    assert CompareSettings.for_run(train_days=60, days=1, seed=0, quick=True).test_days == 1
    assert build_parser().parse_args(["compare", "--scenario", "x", "--quick"]).days is None
    assert SweepSettings.for_run(days=5, quick=True).test_days == 5
    assert SweepSettings.for_run(days=None, quick=True).test_days == 2
    assert SweepSettings.for_run(days=None, quick=False).test_days == 3


def test_compare_rejects_an_unknown_training_policy():
    with pytest.raises(ValueError, match="unknown policy 'thermostat'"):
        CompareSettings(train_days=1, test_days=1, seed=0, policy="thermostat")
    with pytest.raises(ValueError, match="train_days must be >= 1"):
        CompareSettings(train_days=0, test_days=1, seed=0)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--scenario", "mars_base"], "unknown scenario 'mars_base'"),
        (["--json", "{tmp}/file.txt/table.json"], "is a file, not a directory"),
    ],
)
def test_compare_bad_input_exits_2_before_any_work(tmp_path, capsys, args, message):
    (tmp_path / "file.txt").write_text("x")
    args = [a.format(tmp=tmp_path) for a in args]
    argv = ["compare", "--quick", "--report", str(tmp_path / "out" / "report.md"), *args]
    if "--json" not in args:
        argv += ["--json", str(tmp_path / "out" / "table.json")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file.txt"]


@pytest.mark.slow
def test_compare_quick_end_to_end(tmp_path, capsys):
    out = tmp_path / "compare"  # does not exist yet: the command creates it
    code = main(["compare", "--quick", "--train-days", "14", "--days", "1", "--seed", "0",
                 "--json", str(out / "table.json"), "--report", str(out / "report.md")])
    assert code == 0
    table = json.loads((out / "table.json").read_text())
    assert_record(table, CompareTable)  # rows, RC summaries and prediction rows as declared
    labels = [row["controller"] for row in table["rows"]]
    assert labels == [
        "thermostat", "random-shooting / hybrid", "cem / hybrid, no LP polish", "cem / hybrid",
        "cem / physnet", "cem / physreg", "cem / mlp", "cem / ARX", "cem / Physics-informed ARX",
        "casadi-mpc / identified RC",
        "qp-mpc / identified RC", "qp-mpc / hybrid RC", "qp-mpc / physnet RC", "qp-mpc / ARX",
        "qp-mpc / Physics-informed ARX", "oracle", "clairvoyant",
    ]
    rows = {row["controller"]: row for row in table["rows"]}
    for row in table["rows"]:
        assert set(KPI_KEYS) <= set(row) and row["days"] == 1
    assert rows["oracle"]["objective_to_oracle"] == pytest.approx(1.0)
    # The reference with the true model must beat the rule-based baseline on its own objective.
    assert rows["oracle"]["objective"] < rows["thermostat"]["objective"]
    assert set(table["rc"]) == {"true", "identified", "hybrid export", "physnet export"}
    # Every model's 24-step prediction error on held-out test-part data, same starts for all;
    # on paper_household the plant is the 2R2C, so the true RC predicts best among the RCs.
    prediction = {row["model"]: row for row in table["prediction"]}
    assert set(prediction) == {
        "hybrid", "physnet", "physreg", "mlp", "ARX", "Physics-informed ARX", "identified RC", "hybrid RC",
        "physnet RC",
        "true RC",
    }
    assert len({row["n_starts"] for row in table["prediction"]}) == 1
    assert all(set(row["T_r_mae_by_horizon_c"]) == {"1", "6", "24", "48"} for row in prediction.values())
    # the 2R2C plant is linear: the ARX baseline, fitted on the same data, predicts it closely
    assert prediction["ARX"]["T_r_mae_by_horizon_c"]["48"] < 0.1
    assert prediction["true RC"]["T_r_mae_c"] < 0.05
    assert prediction["true RC"]["T_r_mae_c"] <= prediction["physnet RC"]["T_r_mae_c"]
    # Training from the first day of the training weather, test days (after a warm-up day) from
    # the test weather: both ranges in the JSON and the report.
    weather = get_scenario("paper_household").weather
    first_train, first_test = pd.Timestamp(weather.start), pd.Timestamp(weather.test_start)
    day = pd.Timedelta(days=1)
    assert table["training_dates"] == [f"{first_train:%Y-%m-%d}", f"{first_train + 13 * day:%Y-%m-%d}"]
    assert table["test_dates"] == [f"{first_test + day:%Y-%m-%d}"] * 2
    assert table["settings"]["test_dates"] == table["test_dates"]
    assert all(row["weather_part"] == "test" for row in table["rows"])
    report = (out / "report.md").read_text()
    first, last = table["training_dates"]
    assert f"Training data: 14 days, {first} to {last}, from the training part" in report
    assert f"Test: 1 days, {table['test_dates'][0]} to {table['test_dates'][1]}, from the test part" in report
    assert "## KPIs" in report and "## RC parameters" in report and "(report.png)" in report
    assert "## Prediction" in report
    assert (out / "report.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    printed = capsys.readouterr().out
    assert all(label in printed for label in labels)


def test_too_little_data_names_each_option_with_the_command_that_takes_it():
    """The library names the settings; compare takes neither --depth nor --horizons, so the
    command line names the command whose options they are."""
    from pinn_mpc.features import fit_feature_config
    from pinn_mpc_cli.parser import build_parser, command_flags

    with pytest.raises(InputError, match=r"give more data \(more training days\), or a smaller depth$") as caught:
        fit_feature_config(pd.DataFrame({"T_r": [20.0] * 5}), depth=8)
    parser = build_parser()
    assert caught.value.text(command_flags(parser, "compare")).endswith(
        "give more data (--train-days), or a smaller train --depth"
    )
    assert caught.value.text(command_flags(parser, "train")).endswith(
        "give more data (compare --train-days), or a smaller --depth"
    )
