"""A stand-in for a BOPTEST server, for the client's tests: not BOPTEST. It answers the routes
the client calls with fixed envelopes so the client's behaviour can be tested; no emulator runs
behind it and none of its numbers is BOPTEST's.

:class:`StandIn` is an HTTP server (``http.server.ThreadingHTTPServer``) on 127.0.0.1 at a
free port, serving from a thread of its own; the fixture ``standin`` starts one per test. It
answers in BOPTEST's envelope ``{"status", "message", "payload"}`` (and, as BOPTEST's service
does, ``GET /testcases`` and ``GET /status/{id}`` without one, ``PUT /stop/{id}`` with ``OK``,
an unknown test id with status 400 and ``{"errors": [{"msg": "Invalid testid: ID"}]}``). A
test can make it:

- give an error reply on a route (:meth:`StandIn.fail`: a status and a message);
- forget a test, as a server that ended it (:meth:`StandIn.end`);
- accept a route's connection and never answer (:meth:`StandIn.hang`);
- offer other test cases than :data:`TESTCASE` (``testcases``);
- keep a selected test queued for a number of status questions (``queued_polls``), or answer
  no ``select-async`` (``async_select = False``: 404, a server without the route);
- run a function of the route as a request arrives, before it is answered (``on_request``,
  e.g. to send a signal while a select is in flight);

and it records every call it received (``calls``: method, path, body) and the test ids it
gave (``selected``).
"""

from __future__ import annotations

import json
import socket
import threading
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import pytest

__all__ = ["TESTCASE", "Call", "StandIn", "free_port", "standin_server"]

#: The one test case the stand-in offers.
TESTCASE = "standin_case"
#: Its control step [s] until a test sets another.
STEP_S = 3600.0


def free_port() -> int:
    """A local port nothing listens on (as the call returns)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass(frozen=True)
class Call:
    """One request the stand-in received."""

    method: str
    path: str
    body: Any


class StandIn:
    """The stand-in server (see the module docstring); ``url`` is its address."""

    def __init__(self) -> None:
        self.calls: list[Call] = []
        self.selected: list[str] = []
        self.testcases = [TESTCASE]
        self.async_select = True
        self.queued_polls = 0
        self.on_request: Callable[[str], None] | None = None
        self._errors: dict[str, tuple[int, str]] = {}
        self._hanging: set[str] = set()
        self._tests: dict[str, dict[str, Any]] = {}
        self._lock = threading.Lock()
        self._release = threading.Event()
        self._server = ThreadingHTTPServer(("127.0.0.1", 0), _handler(self))
        self._server.daemon_threads = True
        host, port = self._server.server_address[:2]
        self.url = f"http://{host!s}:{port}"
        self._thread = threading.Thread(target=self._server.serve_forever, args=(0.05,), daemon=True)

    # --- what a test asks of it ----------------------------------------------------------------
    def fail(self, route: str, status: int, message: str) -> None:
        """Answer ``route`` (its first path segment, ``select`` or ``select-async`` for a
        select) with an error envelope of ``status`` carrying ``message``."""
        self._errors[route] = (status, message)

    def hang(self, route: str) -> None:
        """Accept ``route``'s connections and never answer them."""
        self._hanging.add(route)

    def end(self, testid: str) -> None:
        """Forget ``testid``, as a server that ended the test."""
        with self._lock:
            self._tests.pop(testid, None)

    def routes(self, method: str | None = None) -> list[str]:
        """The paths of the calls received (of ``method`` only, if given), in order."""
        return [c.path for c in self.calls if method is None or c.method == method]

    # --- lifecycle -----------------------------------------------------------------------------
    def start(self) -> None:
        self._thread.start()

    def close(self) -> None:
        self._release.set()  # hanging handlers return (without an answer)
        self._server.shutdown()
        self._server.server_close()
        self._thread.join(5.0)

    # --- answers -------------------------------------------------------------------------------
    def answer(self, method: str, path: str, body: Any) -> tuple[int, Any] | None:
        """(HTTP status, JSON body) of a request; None: never answer."""
        with self._lock:
            self.calls.append(Call(method, path, body))
        parts = path.strip("/").split("/")
        route = parts[-1] if parts[0] == "testcases" and len(parts) == 3 else parts[0]
        if self.on_request is not None:
            self.on_request(route)
        if route in self._hanging:
            self._release.wait()
            return None
        if route in self._errors:
            status, message = self._errors[route]
            return status, {"status": status, "message": message, "payload": None}
        if route == "version":
            return 200, _envelope("Queried the version number successfully.", {"version": "standin"})
        if route == "testcases":
            return 200, [{"testcaseid": name} for name in self.testcases]
        if route in ("select", "select-async"):
            return self._select(parts[1], queued=route == "select-async")
        with self._lock:
            test = self._tests.get(parts[1]) if len(parts) == 2 else None
        if test is None:
            return 400, {"errors": [{"type": "field", "msg": f"Invalid testid: {parts[-1]}",
                                     "path": "testid", "location": "params"}]}
        return self._test_route(method, route, parts[1], test, body)

    def _select(self, testcase: str, *, queued: bool) -> tuple[int, Any]:
        if queued and not self.async_select:
            return 404, "Not Found"
        if testcase not in self.testcases:
            return 404, "Not Found"
        testid = str(uuid.uuid4())
        with self._lock:
            self._tests[testid] = {"time": 0.0, "step": STEP_S, "polls": self.queued_polls if queued else 0}
            self.selected.append(testid)
        return 200, {"testid": testid}

    def _test_route(self, method: str, route: str, testid: str, test: dict[str, Any], body: Any) -> tuple[int, Any]:
        if route == "status":
            if test["polls"] > 0:
                test["polls"] -= 1
                return 200, "Queued"
            return 200, "Running"
        if route == "stop":
            self.end(testid)
            return 200, "OK"
        if route == "name":
            return 200, _envelope("Queried the name of the test case successfully.", {"name": TESTCASE})
        if route == "step":
            if method == "PUT":
                test["step"] = float(body["step"])
                return 200, _envelope("Setting control step successfully.", None)
            return 200, _envelope("Queried the control step successfully.", test["step"])
        if route == "scenario":
            if method == "PUT":
                test["scenario"] = dict(body)
                payload = {**body, "time_period": {"time": test["time"]}} if "time_period" in body else dict(body)
                return 200, _envelope("Scenario set successfully.", payload)
            return 200, _envelope("Queried the scenario successfully.", test.get("scenario", {}))
        if route == "advance":
            test["time"] += test["step"]
            return 200, _envelope("Advanced the simulation.", {"time": test["time"], **body})
        if route == "forecast":
            n = int(body["horizon"] // body["interval"]) + 1
            times = [test["time"] + i * body["interval"] for i in range(n)]
            values = {name: [0.0] * n for name in body["point_names"]}
            return 200, _envelope("Queried the forecast successfully.", {"time": times, **values})
        if route == "kpi":
            return 200, _envelope("Queried the KPIs successfully.", {"tdis_tot": 0.0, "ener_tot": 0.0, "pele_tot": None})
        return 404, "Not Found"


def _envelope(message: str, payload: Any) -> dict[str, Any]:
    return {"status": 200, "message": message, "payload": payload}


def _handler(standin: StandIn) -> type[BaseHTTPRequestHandler]:
    class Handler(BaseHTTPRequestHandler):
        def _serve(self) -> None:
            length = int(self.headers.get("Content-Length") or 0)
            raw = self.rfile.read(length) if length else b""
            body = json.loads(raw) if raw else None
            answer = standin.answer(self.command, self.path, body)
            if answer is None:
                self.close_connection = True
                return
            status, content = answer
            data = json.dumps(content).encode()
            try:
                self.send_response(status)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                self.wfile.write(data)
            except (BrokenPipeError, ConnectionResetError):  # the client gave up (its timeout)
                self.close_connection = True

        do_GET = do_PUT = do_POST = _serve

        def log_message(self, format: str, *args: Any) -> None:  # quiet
            return

    return Handler


@pytest.fixture(name="standin")
def standin_server() -> Iterator[StandIn]:
    """A :class:`StandIn` serving for one test."""
    server = StandIn()
    server.start()
    try:
        yield server
    finally:
        server.close()
