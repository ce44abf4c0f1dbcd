"""The client of BOPTEST's web API against a stand-in server (:mod:`tests.boptest_standin`, not
BOPTEST): the routes it calls and what it returns, its errors, its timeouts, and that every
test it selects is stopped however the code around it is left. No emulator runs: nothing here
says anything of BOPTEST's emulator or KPIs (tests/test_boptest.py does, against a server)."""

from __future__ import annotations

import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import closing
from pathlib import Path

import numpy as np
import pytest

from pinn_mpc.errors import InputError
from scenarios.plants.boptest import BoptestPlant, BoptestRun, BoptestSettings, read_boptest_file
from scenarios.plants.boptest_client import (
    PROBE_TIMEOUT_S,
    BoptestClient,
    BoptestError,
    BoptestTestEnded,
    BoptestTimeout,
    BoptestUnreachable,
)
from tests.boptest_standin import TESTCASE, StandIn, free_port, standin_server  # noqa: F401  (the fixture)

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "plants" / "boptest_hydronic_heat_pump.toml"
#: Seconds a failing call may take beyond its timeout on a loaded test machine.
SLACK_S = 3.0


def _signal_on(route: str, signum: int = signal.SIGINT) -> Callable[[str], None]:
    """The stand-in's ``on_request``: ``signum`` to the main thread (where Python runs signal
    handlers, as a terminal's Ctrl-C reaches a CLI) as a request of ``route`` arrives, before
    it is answered; once."""
    sent: list[str] = []

    def on_request(arrived: str) -> None:
        if arrived == route and not sent:
            sent.append(route)
            signal.pthread_kill(threading.main_thread().ident or 0, signum)
            time.sleep(0.05)  # the signal is taken while the request is in flight

    return on_request


@pytest.fixture
def exit_on_sigterm() -> Iterator[None]:
    """SIGTERM raises SystemExit in the main thread, as in a Ray worker."""

    def handler(signum: int, frame: object) -> None:
        sys.exit(1)

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


# --- routes and payloads -------------------------------------------------------------------------


def test_routes_and_the_payloads_returned(standin: StandIn) -> None:
    with closing(BoptestClient(standin.url)) as client:
        assert client.version() == "standin"
        assert client.testcases() == [TESTCASE]
        with client.select(TESTCASE) as test:
            testid = test.testid
            assert test.name() == TESTCASE
            test.set_step(1800.0)
            assert test.step_s() == 1800.0
            start = test.set_scenario(time_period="peak_heat_day", electricity_price="dynamic")
            assert start == {"time_period": {"time": 0.0}, "electricity_price": "dynamic"}
            assert test.scenario() == {"time_period": "peak_heat_day", "electricity_price": "dynamic"}
            assert test.advance({"oveU_u": 0.5, "oveU_activate": 1}) == {
                "time": 1800.0, "oveU_u": 0.5, "oveU_activate": 1.0,
            }
            fc = test.forecast(["TDryBul"], horizon_s=3600.0, interval_s=1800.0)
            assert list(fc) == ["time", "TDryBul"] and fc["TDryBul"].dtype == np.float64
            np.testing.assert_array_equal(fc["time"], [1800.0, 3600.0, 5400.0])
            assert test.kpi() == {"tdis_tot": 0.0, "ener_tot": 0.0, "pele_tot": None}
    assert test.stopped and client.tests == {}
    assert client.server_version == "standin"  # the probe's answer, which a run's KPIs record
    assert [(c.method, c.path) for c in standin.calls] == [
        ("GET", "/version"), ("GET", "/testcases"),
        ("GET", "/version"),  # the probe before the first select
        ("POST", f"/testcases/{TESTCASE}/select-async"), ("GET", f"/status/{testid}"),
        ("GET", f"/name/{testid}"), ("PUT", f"/step/{testid}"), ("GET", f"/step/{testid}"),
        ("PUT", f"/scenario/{testid}"), ("GET", f"/scenario/{testid}"),
        ("POST", f"/advance/{testid}"), ("PUT", f"/forecast/{testid}"), ("GET", f"/kpi/{testid}"),
        ("PUT", f"/stop/{testid}"),
    ]
    assert standin.calls[6].body == {"step": 1800.0}
    # leaving the block stopped the test: the client refuses further calls, the server too
    with pytest.raises(BoptestTestEnded, match="was stopped"):
        test.kpi()
    with pytest.raises(BoptestTestEnded, match=f"test {testid} is no longer on the server"):
        BoptestClient(standin.url).call("GET", f"kpi/{testid}", testid=testid)


def test_a_queued_test_is_waited_for_and_a_server_without_select_async_gets_the_plain_select(
    standin: StandIn,
) -> None:
    standin.queued_polls = 2
    with closing(BoptestClient(standin.url)) as client, client.select(TESTCASE) as test:
        assert standin.routes("GET")[-3:] == [f"/status/{test.testid}"] * 3  # queued, queued, running
    standin.async_select = False
    with closing(BoptestClient(standin.url)) as client, client.select(TESTCASE) as test:
        pass
    assert standin.routes("POST")[-2:] == [
        f"/testcases/{TESTCASE}/select-async", f"/testcases/{TESTCASE}/select",
    ]
    assert standin.routes()[-1] == f"/stop/{test.testid}"
    assert f"/status/{test.testid}" not in standin.routes()  # the plain select answers once running


# --- errors ------------------------------------------------------------------------------------


def test_an_error_reply_becomes_boptest_error_carrying_its_message(standin: StandIn) -> None:
    standin.fail("advance", 400, "Unexpected input variable: oveNope_u")
    with closing(BoptestClient(standin.url)) as client, client.select(TESTCASE) as test:
        with pytest.raises(BoptestError, match=r"refused POST /advance/\S+ \(status 400\): Unexpected input variable: oveNope_u") as caught:
            test.advance({"oveNope_u": 1.0})
    assert caught.value.status == 400 and isinstance(caught.value, InputError)
    assert "\n" not in str(caught.value)
    with pytest.raises(BoptestError, match="refused POST /testcases/nope/select \\(status 404\\)"):
        BoptestClient(standin.url).select("nope")


def test_a_test_the_server_ended_is_reported_as_such(standin: StandIn) -> None:
    with closing(BoptestClient(standin.url)) as client:
        test = client.select(TESTCASE)
        standin.end(test.testid)  # as BOPTEST ends a test left idle
        with pytest.raises(BoptestTestEnded, match=f"test {test.testid} is no longer on the server .*idle timeout.*Invalid testid: {test.testid}"):
            test.step_s()
        test.stop()  # nothing left to stop: no error
    assert test.stopped and standin.routes("PUT") == [f"/stop/{test.testid}"]


def test_an_unreachable_server_is_one_line_naming_the_url_and_boptest_url() -> None:
    url = f"http://127.0.0.1:{free_port()}"
    with pytest.raises(BoptestUnreachable) as caught:
        BoptestClient(url, timeout_s=5).version()
    message = str(caught.value)
    assert "\n" not in message and url in message and "BOPTEST_URL" in message
    assert "docker compose up" in message and "https://github.com/ibpsa/project1-boptest" in message
    assert "see docs/boptest.md" in message and "shared/boptest" not in message
    assert isinstance(caught.value, InputError)  # the CLI's one line and exit 2
    points = read_boptest_file(str(SCENARIO)).points
    with pytest.raises(BoptestUnreachable, match="no BOPTEST server answers at http://127.0.0.1"):
        BoptestPlant(BoptestSettings(points=points, url=url), BoptestRun(days=1))


def test_a_call_that_never_answers_fails_after_its_timeout(standin: StandIn) -> None:
    standin.hang("kpi")
    with closing(BoptestClient(standin.url, timeout_s=0.5)) as client, client.select(TESTCASE) as test:
        start = time.monotonic()
        with pytest.raises(BoptestTimeout, match=r"GET /kpi/\S+ gave no answer within 0.5 s"):
            test.kpi()
        assert time.monotonic() - start < 0.5 + SLACK_S
    assert standin.routes("PUT") == [f"/stop/{test.testid}"]


def test_a_server_that_never_answers_is_reported_before_the_select(standin: StandIn) -> None:
    """It accepts the connection and answers nothing: the probe says so within seconds,
    where the select would wait its 300 s."""
    standin.hang("version")
    start = time.monotonic()
    with pytest.raises(BoptestUnreachable) as caught:
        BoptestClient(standin.url).select(TESTCASE)
    assert time.monotonic() - start < PROBE_TIMEOUT_S + SLACK_S
    message = str(caught.value)
    assert "\n" not in message
    assert f"the BOPTEST server at {standin.url} did not answer within 5 s (GET /version)" in message
    assert f"curl {standin.url}/version" in message and "BOPTEST_URL" in message
    assert standin.routes() == ["/version"]  # no select


@pytest.mark.parametrize("command", [
    ["closed-loop", "--controller", "thermostat", "--days", "1", "--json", "k.json"],
    ["sweep", "--controllers", "thermostat", "--seeds", "0", "--days", "1", "--out", "sweep"],
], ids=["closed-loop", "sweep"])
def test_a_command_on_a_server_that_never_answers_fails_at_once(
    standin: StandIn, command: list[str], monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str], tmp_path: Path,
) -> None:
    from pinn_mpc_cli.cli import main

    standin.hang("version")
    monkeypatch.setenv("BOPTEST_URL", standin.url)
    monkeypatch.chdir(tmp_path)
    scenario = "--scenarios" if command[0] == "sweep" else "--scenario"
    start = time.monotonic()
    code = main([*command, scenario, "boptest_hydronic_heat_pump"])
    # the probe's 5 s and the command's imports, where the select waited 300 s (a sweep's
    # check of the server 120 s)
    assert time.monotonic() - start < PROBE_TIMEOUT_S + 15.0
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err  # before any stage says it starts
    assert f"the BOPTEST server at {standin.url} did not answer within 5 s" in err
    assert not list(tmp_path.iterdir())


# --- every test selected is stopped ----------------------------------------------------------------


@pytest.mark.parametrize("async_select", [True, False], ids=["select-async", "plain select"])
def test_ctrl_c_while_the_select_is_in_flight_stops_the_test_it_created(
    standin: StandIn, async_select: bool
) -> None:
    """The server creates the test and answers; the interrupt arrived before the answer: the
    test is stopped, then the interrupt goes on."""
    standin.async_select = async_select
    standin.on_request = _signal_on("select-async" if async_select else "select")
    client = BoptestClient(standin.url)
    with pytest.raises(KeyboardInterrupt):
        client.select(TESTCASE)
    assert len(standin.selected) == 1
    assert standin.routes("PUT") == [f"/stop/{standin.selected[0]}"]
    assert client.tests == {}
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_second_ctrl_c_interrupts_a_select_that_does_not_answer_at_once(standin: StandIn) -> None:
    """The first Ctrl-C waits for the select's answer; one who asks again is not held (the
    test the server may have made is left to its idle timeout)."""
    standin.hang("select-async")
    main_thread = threading.main_thread().ident or 0

    def twice(route: str) -> None:
        if route == "select-async":
            for _ in range(2):
                signal.pthread_kill(main_thread, signal.SIGINT)
                time.sleep(0.2)

    standin.on_request = twice
    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        BoptestClient(standin.url).select(TESTCASE)
    assert time.monotonic() - start < SLACK_S  # not the select's 30 s
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_ctrl_c_while_the_test_is_queued_stops_it(standin: StandIn) -> None:
    standin.queued_polls = 5
    standin.on_request = _signal_on("status")
    with pytest.raises(KeyboardInterrupt):
        BoptestClient(standin.url).select(TESTCASE)
    assert standin.routes("PUT") == [f"/stop/{standin.selected[0]}"]


def test_a_sigterm_while_the_select_is_in_flight_stops_the_test_then_exits(
    standin: StandIn, exit_on_sigterm: None
) -> None:
    """A Ray worker turns SIGTERM (the sweep stopped) into SystemExit."""
    standin.on_request = _signal_on("select-async", signal.SIGTERM)
    with pytest.raises(SystemExit):
        BoptestClient(standin.url).select(TESTCASE)
    assert standin.routes("PUT") == [f"/stop/{standin.selected[0]}"]


def test_a_test_whose_with_block_was_never_entered_is_stopped_by_the_clients_close(standin: StandIn) -> None:
    with pytest.raises(KeyboardInterrupt), closing(BoptestClient(standin.url)) as client:
        client.select(TESTCASE)  # interrupted before its `with`: only the client knows it
        raise KeyboardInterrupt
    assert standin.routes("PUT") == [f"/stop/{standin.selected[0]}"]


def test_a_plant_interrupted_while_selecting_stops_the_test(standin: StandIn) -> None:
    points = read_boptest_file(str(SCENARIO)).points
    standin.testcases.append(points.testcase)
    standin.on_request = _signal_on("select-async")
    with pytest.raises(KeyboardInterrupt):
        BoptestPlant(BoptestSettings(points=points, url=standin.url), BoptestRun(days=1))
    assert standin.routes("PUT") == [f"/stop/{standin.selected[0]}"]


# --- what long BOPTEST commands say ----------------------------------------------------------------


@pytest.mark.parametrize(("command", "first_line"), [
    (["simulate", "--days", "4", "--out", "d.csv"],
     "training data on BOPTEST: 4 day(s) from day 30 of the year, closed-loop policy"),
    (["closed-loop", "--controller", "thermostat", "--json", "k.json"],
     "thermostat on BOPTEST: peak_heat_day, 14 day(s), dynamic price"),
    (["compare", "--train-days", "4", "--days", "1", "--quick", "--json", "t.json", "--report", "r.md"],
     "training data on BOPTEST: 4 day(s) from day 30 of the year, closed-loop policy"),
], ids=["simulate", "closed-loop", "compare"])
def test_a_boptest_command_says_what_it_starts_before_the_server_works(
    standin: StandIn, command: list[str], first_line: str, monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str], tmp_path: Path,
) -> None:
    """The stand-in has none of the test case's points, so each command ends with one error
    after its test is selected; before that, its first stage has said what it does (a line a
    minute follows while a stage runs: tests/test_careless_input.py)."""
    from pinn_mpc_cli.cli import main

    standin.testcases.append(read_boptest_file(str(SCENARIO)).points.testcase)
    monkeypatch.setenv("BOPTEST_URL", standin.url)
    monkeypatch.chdir(tmp_path)
    assert main([*command, "--scenario", "boptest_hydronic_heat_pump"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines[0] == first_line
    assert "has no input" in lines[-1] or "refused GET /inputs" in lines[-1]
    assert len(standin.selected) == 1 and standin.routes("PUT")[-1] == f"/stop/{standin.selected[0]}"
