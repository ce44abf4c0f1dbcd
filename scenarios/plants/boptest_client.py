"""A client of BOPTEST's web API (IBPSA Project 1): one test on a server, call by call.

BOPTEST serves a building emulator through HTTP routes keyed by a test id: a client selects a
test case (``POST /testcases/{case}/select`` -> ``{"testid"}``), sets the scenario
(``PUT /scenario/{id}``: a test period and a price scenario, with BOPTEST's warm-up) or
initialises a period of its own (``PUT /initialize/{id}``), sets the control step
(``PUT /step/{id}``), advances one step with its inputs (``POST /advance/{id}`` -> the
measurements at the step's end), asks for forecasts (``PUT /forecast/{id}``), the stored
trajectories (``PUT /results/{id}``) and the KPIs (``GET /kpi/{id}``), and stops the test
(``PUT /stop/{id}``). Every reply is JSON ``{"status", "message", "payload"}`` with that HTTP
status; this client returns the payload and turns everything else into one clear error:

- no server at the URL, or one that does not answer ``GET /version`` within
  :data:`PROBE_TIMEOUT_S` (asked before the first select) -> :class:`BoptestUnreachable` (an
  :class:`~pinn_mpc.errors.InputError`) naming the URL and how to get a server
  (:data:`SERVER_HINT`);
- an error reply (400, 500, ...) -> :class:`BoptestError` carrying BOPTEST's own message;
- a test the server no longer knows (BOPTEST ends a test after a time without calls) ->
  :class:`BoptestTestEnded`;
- no answer within the call's timeout -> :class:`BoptestTimeout` (nothing waits for ever).

Every test a client selects is stopped however the code around it is left. Selecting asks
BOPTEST for the test id at once (``POST /testcases/{case}/select-async``: the test is queued)
and then waits for it to run (``GET /status/{id}``) knowing its id; a server without that
route gets the plain select, which answers once the test runs. While the select request is
in flight, Ctrl-C (SIGINT) and a SIGTERM that Python handles (Ray's workers turn it into
SystemExit) are held back (in the main thread, where Python runs its signal handlers): the
id arrives, the test is stopped, then the interrupt goes on (a second Ctrl-C goes on at once).
:class:`BoptestTest` is a context manager: leaving the ``with`` block in any way (an error,
Ctrl-C) stops the test on the server; :meth:`BoptestClient.close` stops any test of the client
not stopped yet (one whose ``with`` block was never entered).
"""

from __future__ import annotations

import contextlib
import math
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from types import FrameType, TracebackType
from typing import Any

import numpy as np
import requests

from pinn_mpc.errors import InputError

__all__ = [
    "BOPTEST_URL_ENV",
    "DEFAULT_URL",
    "BoptestClient",
    "BoptestError",
    "BoptestTest",
    "BoptestTestEnded",
    "BoptestTimeout",
    "BoptestUnreachable",
    "SERVER_HINT",
    "end_on_exit",
    "server_url",
]

#: Environment variable with the server's address; the default is where BOPTEST's own service
#: listens.
BOPTEST_URL_ENV = "BOPTEST_URL"
DEFAULT_URL = "http://127.0.0.1:8000"
#: How a user gets a BOPTEST server: BOPTEST's own service, or the page on running it without
#: Docker.
SERVER_HINT = (
    "start BOPTEST's service (`docker compose up web worker provision` in a clone of "
    f"https://github.com/ibpsa/project1-boptest; it listens on {DEFAULT_URL}) and set "
    f"{BOPTEST_URL_ENV} to its address; to run it without Docker see docs/boptest.md"
)

#: Seconds to wait for a connection, and for an ordinary call's answer.
CONNECT_TIMEOUT_S = 5.0
CALL_TIMEOUT_S = 120.0
#: Seconds the server has to answer ``GET /version`` before the first select: a server that
#: accepts connections and never answers is reported now, not after a select's timeout.
PROBE_TIMEOUT_S = 5.0
#: Selecting a test loads the emulator: a select gets this long to see it run (queued, then
#: running), and the request that asks for the test id (select-async) this long to answer.
SELECT_TIMEOUT_S = 300.0
SELECT_ID_TIMEOUT_S = 30.0
#: Seconds between two questions of a queued test's status (BOPTEST's own select waits so).
SELECT_POLL_S = 1.0
#: Setting a scenario or initialising simulates the warm-up (days of simulated time).
WARMUP_TIMEOUT_S = 900.0
#: Stopping in an exit path must not hold up the exit for long.
STOP_TIMEOUT_S = 30.0


class BoptestError(InputError):
    """A BOPTEST server refused or failed a call; the message carries BOPTEST's own words and
    ``status`` the reply's HTTP status (None without a reply)."""

    def __init__(self, message: str, *, status: int | None = None) -> None:
        super().__init__(message)
        self.status = status


class BoptestUnreachable(BoptestError):
    """No BOPTEST server answers at the URL."""


class BoptestTimeout(BoptestError):
    """A call got no answer within its timeout."""


class BoptestTestEnded(BoptestError):
    """The test is no longer on the server (stopped, or ended after its idle timeout)."""


def server_url(url: str | None = None) -> str:
    """The server's address: ``url`` when given, else ``$BOPTEST_URL``, else the local default
    ``http://127.0.0.1:8000``; without a trailing slash."""
    chosen = url or os.environ.get(BOPTEST_URL_ENV) or DEFAULT_URL
    if not chosen.startswith(("http://", "https://")):
        raise InputError(
            f"BOPTEST server address {chosen!r} is not an http:// or https:// URL "
            f"(set {BOPTEST_URL_ENV}, e.g. {DEFAULT_URL})"
        )
    return chosen.rstrip("/")


def _reply_text(body: Any, text: str) -> str:
    """BOPTEST's message of an error reply: ``message`` (and a string ``payload`` beside it),
    the ``errors`` list of a rejected request, or the reply's text."""
    if isinstance(body, dict):
        if isinstance(body.get("errors"), list):
            return "; ".join(str(e.get("msg", e)) if isinstance(e, dict) else str(e) for e in body["errors"])
        parts = [str(body.get("message") or "")]
        payload = body.get("payload")
        if isinstance(payload, str) and payload and payload not in parts[0]:
            parts.append(payload.strip().splitlines()[-1])
        return ": ".join(p for p in parts if p) or text.strip()
    return text.strip() or "(empty reply)"


class BoptestClient:
    """The server at ``url`` (see :func:`server_url`), every call with a timeout [s]."""

    def __init__(self, url: str | None = None, *, timeout_s: float = CALL_TIMEOUT_S) -> None:
        if not (math.isfinite(timeout_s) and timeout_s > 0):
            raise ValueError(f"BoptestClient: timeout_s must be > 0 seconds, got {timeout_s!r}")
        self.url = server_url(url)
        self.timeout_s = float(timeout_s)
        self.session = requests.Session()
        self.probed = False
        #: BOPTEST's version as the server reported it (``GET /version``; None before a probe).
        self.server_version: str | None = None
        #: The tests this client selected and has not stopped, by test id.
        self.tests: dict[str, BoptestTest] = {}

    def close(self) -> None:
        """Stop every test of this client not stopped yet, then close the HTTP session. The
        stops are the last resort of an exit path (a test whose ``with`` block was never
        entered): a stop the server refuses is left to its idle timeout, not raised."""
        try:
            for test in list(self.tests.values()):
                with contextlib.suppress(BoptestError):
                    test.stop()
        finally:
            self.session.close()

    def call(
        self, method: str, route: str, body: Mapping[str, Any] | None = None, *,
        timeout_s: float | None = None, testid: str | None = None,
    ) -> Any:
        """One call: ``method`` on ``/route`` with a JSON body; BOPTEST's payload (or, for a
        reply that is not BOPTEST's envelope, the decoded reply). Raises the module's errors."""
        read_s = self.timeout_s if timeout_s is None else timeout_s
        address = f"{self.url}/{route}"
        try:
            response = self.session.request(
                method, address, json=None if body is None else dict(body),
                timeout=(CONNECT_TIMEOUT_S, read_s),
            )
        except requests.ConnectionError as exc:
            if isinstance(exc, requests.ConnectTimeout) or "Connection refused" in str(exc) or \
                    "Failed to establish" in str(exc) or "Name or service" in str(exc):
                raise BoptestUnreachable(
                    f"no BOPTEST server answers at {self.url}: {SERVER_HINT}"
                ) from None
            raise BoptestError(f"BOPTEST at {self.url}: {method} /{route} failed: {exc}") from None
        except requests.Timeout:
            raise BoptestTimeout(
                f"BOPTEST at {self.url}: {method} /{route} gave no answer within {read_s:g} s"
            ) from None
        except requests.RequestException as exc:
            raise BoptestError(f"BOPTEST at {self.url}: {method} /{route} failed: {exc}") from None
        try:
            decoded: Any = response.json()
        except ValueError:
            decoded = None
        if response.status_code != 200:
            message = _reply_text(decoded, response.text)
            if testid is not None and self._test_gone(response.status_code, message, testid):
                raise BoptestTestEnded(
                    f"BOPTEST test {testid} is no longer on the server at {self.url} (BOPTEST "
                    "ends a test after a time without calls, its idle timeout, or it was "
                    f"stopped): {message}; select a new test", status=response.status_code,
                )
            raise BoptestError(
                f"BOPTEST at {self.url} refused {method} /{route} "
                f"(status {response.status_code}): {message}", status=response.status_code,
            )
        if isinstance(decoded, dict) and {"status", "message", "payload"} <= decoded.keys():
            return decoded["payload"]
        return decoded if decoded is not None else response.text

    @staticmethod
    def _test_gone(status: int, message: str, testid: str) -> bool:
        return ("Invalid testid" in message and testid in message) or (
            status >= 500 and "ended" in message and testid in message
        )

    def version(self, *, timeout_s: float | None = None) -> str:
        """BOPTEST's version (``GET /version``)."""
        payload = self.call("GET", "version", timeout_s=timeout_s)
        return str(payload["version"] if isinstance(payload, dict) else payload)

    def probe(self) -> None:
        """Ask the server its version within :data:`PROBE_TIMEOUT_S`: a server that is not
        there, or accepts connections and never answers, is one clear error now."""
        try:
            self.server_version = self.version(timeout_s=PROBE_TIMEOUT_S)
        except BoptestTimeout:
            raise BoptestUnreachable(
                f"the BOPTEST server at {self.url} did not answer within {PROBE_TIMEOUT_S:g} s "
                f"(GET /version): check that it runs and answers (`curl {self.url}/version`); "
                f"else {SERVER_HINT}"
            ) from None
        self.probed = True

    def testcases(self) -> list[str]:
        """The test cases the server has (``GET /testcases``)."""
        payload = self.call("GET", "testcases")
        return [str(t["testcaseid"] if isinstance(t, dict) else t) for t in payload]

    def select(self, testcase: str) -> BoptestTest:
        """Start a test of ``testcase`` and wait until it runs: the test id at once
        (``POST /testcases/{testcase}/select-async``), then ``GET /status/{id}`` every
        :data:`SELECT_POLL_S` until it runs, at most :data:`SELECT_TIMEOUT_S`; a server
        without select-async gets the plain ``select``. The server is probed first
        (:meth:`probe`, once per client). Interrupted or failing after the id arrived, the
        test is stopped before the error goes on (see the module docstring)."""
        if not self.probed:
            self.probe()
        test: BoptestTest | None = None
        try:
            with _exits_held():
                testid, queued = self._select_id(testcase)
                test = BoptestTest(self, testid, testcase)
            if queued:
                self._wait_running(test)
        except BaseException:
            if test is not None:
                end_on_exit(test.stop, failed=True)
            raise
        return test

    def _select_id(self, testcase: str) -> tuple[str, bool]:
        """The new test's id, and whether it may still be queued (select-async's answer)."""
        route = f"testcases/{testcase}/select"
        try:
            payload, queued = self.call("POST", f"{route}-async", timeout_s=SELECT_ID_TIMEOUT_S), True
        except BoptestError as exc:
            # no such route (404 on BOPTEST's service; a server of the API may say it another
            # way); a refusal of the test case itself comes again from the plain select
            if exc.status is None or not 400 <= exc.status < 500:
                raise
            payload, queued = self.call("POST", route, timeout_s=SELECT_TIMEOUT_S), False
        if not (isinstance(payload, dict) and isinstance(payload.get("testid"), str)):
            raise BoptestError(f"BOPTEST at {self.url}: select {testcase} gave no test id: {payload!r}")
        return payload["testid"], queued

    def _wait_running(self, test: BoptestTest) -> None:
        """Wait until BOPTEST reports ``test`` running (it is queued until a worker has
        loaded the test case)."""
        waited_from = time.monotonic()
        while True:
            status = str(self.call("GET", f"status/{test.testid}", testid=test.testid)).strip()
            if status == "Running":
                return
            if status != "Queued":
                raise BoptestError(
                    f"BOPTEST at {self.url}: test {test.testid} of {test.testcase} is "
                    f"{status!r}, neither queued nor running"
                )
            if time.monotonic() - waited_from >= SELECT_TIMEOUT_S:
                raise BoptestError(
                    f"BOPTEST at {self.url}: test {test.testid} of {test.testcase} was still "
                    f"queued after {SELECT_TIMEOUT_S:g} s (BOPTEST runs as many tests at once as "
                    "it has workers: `docker compose up --scale worker=N`); it was stopped"
                )
            time.sleep(SELECT_POLL_S)


@contextlib.contextmanager
def _exits_held() -> Iterator[None]:
    """Within (in the main thread, where Python runs signal handlers): SIGINT, and SIGTERM
    where a Python handler takes it, are held back and handed to their handler as the block
    ends (Ctrl-C's KeyboardInterrupt, a Ray worker's SystemExit); a second one of a kind goes
    on at once. Elsewhere the block runs as it is: no handler can interrupt it there."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    previous: dict[int, Callable[[int, FrameType | None], Any]] = {}

    def hold(signum: int, frame: FrameType | None) -> None:
        if signum in caught:  # asked twice: go on now, leaving the test to the server
            caught.remove(signum)
            previous[signum](signum, frame)
            return
        caught.append(signum)

    for held in (signal.SIGINT, signal.SIGTERM):
        handler = signal.getsignal(held)
        if callable(handler):
            previous[held] = handler
            signal.signal(held, hold)
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        for signum in dict.fromkeys(caught):
            previous[signum](signum, None)


def _floats(series: Mapping[str, Any]) -> dict[str, np.ndarray]:
    return {name: np.asarray(values, dtype=float) for name, values in series.items()}


class BoptestTest:
    """One test on a BOPTEST server: the routes keyed by its test id. Use it as a context
    manager (or call :meth:`stop`): the test stops on the server however the block is left."""

    def __init__(self, client: BoptestClient, testid: str, testcase: str) -> None:
        self.client, self.testid, self.testcase = client, testid, testcase
        self.stopped = False
        client.tests[testid] = self  # stopped by the client's close if nothing else does

    def _call(self, method: str, action: str, body: Mapping[str, Any] | None = None,
              timeout_s: float | None = None) -> Any:
        if self.stopped:
            raise BoptestTestEnded(f"BOPTEST test {self.testid} was stopped; select a new test")
        return self.client.call(
            method, f"{action}/{self.testid}", body, timeout_s=timeout_s, testid=self.testid
        )

    # --- what the test case is ---------------------------------------------------------------
    def name(self) -> str:
        """The test case's name (``GET /name``)."""
        return str(self._call("GET", "name")["name"])

    def inputs(self) -> dict[str, dict[str, Any]]:
        """The inputs a controller may overwrite, with unit, description, minimum, maximum."""
        return dict(self._call("GET", "inputs"))

    def measurements(self) -> dict[str, dict[str, Any]]:
        """The measured points, with unit and description."""
        return dict(self._call("GET", "measurements"))

    def forecast_points(self) -> dict[str, dict[str, Any]]:
        """The points ``forecast`` can give, with unit and description."""
        return dict(self._call("GET", "forecast_points"))

    # --- the test's clock --------------------------------------------------------------------
    def step_s(self) -> float:
        """The control step [s] (``GET /step``)."""
        return float(self._call("GET", "step"))

    def set_step(self, step_s: float) -> None:
        """Set the control step [s] (``PUT /step``)."""
        self._call("PUT", "step", {"step": float(step_s)})

    def initialize(self, start_time_s: float, warmup_period_s: float) -> dict[str, float]:
        """Start at ``start_time_s`` [s of the year] after a warm-up of ``warmup_period_s``;
        the measurements then (``PUT /initialize``). No KPI period end: for data, not tests."""
        payload = self._call(
            "PUT", "initialize",
            {"start_time": float(start_time_s), "warmup_period": float(warmup_period_s)},
            timeout_s=WARMUP_TIMEOUT_S,
        )
        return {k: float(v) for k, v in payload.items()}

    def set_scenario(
        self, *, time_period: str | None = None, electricity_price: str | None = None
    ) -> dict[str, Any]:
        """BOPTEST's scenario (``PUT /scenario``): a test period (initialises the test at its
        start after BOPTEST's warm-up) and/or a price scenario. BOPTEST's payload: the
        measurements at the period's start under ``time_period``."""
        body = {k: v for k, v in (("time_period", time_period), ("electricity_price", electricity_price)) if v}
        timeout = WARMUP_TIMEOUT_S if time_period else None
        return dict(self._call("PUT", "scenario", body, timeout_s=timeout))

    def scenario(self) -> dict[str, Any]:
        """The scenario set (``GET /scenario``)."""
        return dict(self._call("GET", "scenario"))

    # --- running -----------------------------------------------------------------------------
    def advance(self, inputs: Mapping[str, float] | None = None) -> dict[str, float]:
        """One control step with ``inputs`` overwritten (``POST /advance``; none: the test
        case's own controller acts); the measurements and inputs at the step's end (empty once
        the test period is over)."""
        payload = self._call("POST", "advance", dict(inputs or {}))
        return {k: float(v) for k, v in (payload or {}).items()}

    def forecast(
        self, point_names: Sequence[str], *, horizon_s: float, interval_s: float
    ) -> dict[str, np.ndarray]:
        """Forecasts of ``point_names`` from now over ``horizon_s`` every ``interval_s``
        (``PUT /forecast``), arrays with ``time`` [s of the year]."""
        payload = self._call(
            "PUT", "forecast",
            {"point_names": list(point_names), "horizon": float(horizon_s), "interval": float(interval_s)},
        )
        return _floats(payload)

    def results(
        self, point_names: Sequence[str], *, start_time_s: float, final_time_s: float
    ) -> dict[str, np.ndarray]:
        """The stored trajectories of ``point_names`` between the two times (``PUT
        /results``), arrays with ``time`` [s of the year]."""
        payload = self._call(
            "PUT", "results",
            {"point_names": list(point_names), "start_time": float(start_time_s),
             "final_time": float(final_time_s)},
        )
        return _floats(payload)

    def kpi(self) -> dict[str, float | None]:
        """BOPTEST's KPIs of the test so far (``GET /kpi``), None where not applicable."""
        payload = self._call("GET", "kpi")
        return {k: None if v is None else float(v) for k, v in payload.items()}

    def stop(self) -> None:
        """Stop the test on the server (``PUT /stop``); once only, later calls do nothing. A
        test the server has already ended needs no stopping."""
        if self.stopped:
            return
        self.stopped = True
        self.client.tests.pop(self.testid, None)
        try:
            self.client.call("PUT", f"stop/{self.testid}", timeout_s=STOP_TIMEOUT_S, testid=self.testid)
        except BoptestTestEnded:
            pass

    def __enter__(self) -> BoptestTest:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        end_on_exit(self.stop, failed=exc_type is not None)


def end_on_exit(end: Callable[[], None], *, failed: bool) -> None:
    """Run ``end`` (stop a test, close a plant) as a ``with`` block is left: its error is raised
    after a clean block, but when the block is left on an error or Ctrl-C, a BOPTEST error of
    ``end`` is dropped so that the first error is the one reported."""
    if not failed:
        end()
        return
    try:
        end()
    except BoptestError:
        pass
