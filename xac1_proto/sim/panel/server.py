"""The front panel's web server: a page, a JSON API and a live feed beside a running simulator.

How it works: ``Panel(host, port)`` binds its socket at once (a port in use or a host that is not this
machine's is a ``PanelError`` before anything starts). ``tap`` is the simulator's ``on_traffic`` hook
and ``fact`` its control channel's (``control.ControlChannel``): both only append to a deque, in the
simulator's thread, so the pty round trip pays one append. ``start(sim, control)`` runs a Starlette app
under uvicorn on an event loop of its own thread. There a pump wakes every ``POLL_S`` and moves the
deque into ``HISTORY``, the line's recent past. The line is judged (``line.LineWatch``, the one
rulebook) only while someone looks: the first listener, or a ``GET /api/line``, judges the history
from its first host line on, then the pump judges what comes while a browser listens, reads the device
state under the simulator's lock and sends what changed on the live feed. With no browser the engine
does not run, so it takes nothing from the simulator's thread.

The API: ``GET /`` the page (self-contained: no file from elsewhere, it works offline); ``GET
/api/state`` the device state (``state.state_of``); ``GET /api/line`` the last exchanges with their
verdicts; ``POST /api/control`` a control command's text (the stdin channel's commands, through the same
``ControlChannel``), answered ``{"ok": true, "command", "result"}`` or 400 ``{"ok": false, "command",
"error"}`` (403 when a page of another origin sends it: a web page elsewhere must not drive it);
``GET /api/feed`` Server-Sent Events: ``state`` (the whole state, at once and on every change) and
``line`` (new rows).
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import json
import socket
import threading
import time
from collections import deque
from collections.abc import AsyncIterator, Callable, Iterator
from importlib import resources
from typing import TYPE_CHECKING, Any, Final

import uvicorn
from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import HTMLResponse, JSONResponse, Response, StreamingResponse
from starlette.routing import Route

from ..control import Fact
from .line import LineWatch
from .state import state_of

if TYPE_CHECKING:
    from ..runner import RunningSim

POLL_S: Final = 0.1  # how often the pump looks at the deque and, while a browser listens, at the state
HISTORY: Final = 4096  # chunks and facts of the line kept for a browser that comes
MAX_COMMAND: Final = 200  # characters a control command may have
STOP_WAIT_S: Final = 5.0


class PanelError(OSError):
    """The panel's address cannot be served (one line for the user)."""


def bind(host: str, port: int, flag: str = "--panel") -> socket.socket:
    """A listening socket on ``host:port``; ``PanelError`` saying why not."""
    where = f"{flag} {host}:{port}"
    try:
        family, _, _, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM,
                                                      flags=socket.AI_PASSIVE)[0]
    except (socket.gaierror, UnicodeError) as exc:
        raise PanelError(f"{where}: no such host ({getattr(exc, 'strerror', None) or exc})") from None
    try:
        return socket.create_server(address[:2], family=family)
    except OSError as exc:
        if exc.errno == errno.EADDRINUSE:
            raise PanelError(f"{where}: the port is in use") from None
        raise PanelError(f"{where}: cannot listen there ({exc.strerror or exc})") from None


def _judge(watch: LineWatch, item: tuple[Any, ...]) -> None:
    """One inbox item to the engine: bytes of the line, or a fact of the control channel."""
    if item[0] == "bytes":
        watch.feed(*item[1:])
    elif item[0] == "stop-input":
        watch.stop_input(*item[1:])
    else:
        watch.power_on()


def _sse(event: str, data: object) -> str:
    return f"event: {event}\ndata: {json.dumps(data, separators=(',', ':'))}\n\n"


class Panel:
    """The front panel of one simulator; see the module docstring."""

    def __init__(self, host: str = "127.0.0.1", port: int = 0) -> None:
        self._socket = bind(host, port)
        self.host, self.port = self._socket.getsockname()[:2]
        shown = f"[{self.host}]" if ":" in self.host else self.host
        self.url = f"http://{shown}:{self.port}/"
        self._watch: LineWatch | None = None  # the line judged, while someone looks
        self._inbox: deque[tuple[Any, ...]] = deque()  # ("bytes", t, dir, data) or a control Fact
        self._history: deque[tuple[Any, ...]] = deque(maxlen=HISTORY)
        self._listeners: set[asyncio.Queue[str | None]] = set()
        self._state: dict[str, Any] | None = None  # the state last sent on the feed
        self._sent = 0  # rows sent on the feed
        self._sim: RunningSim | None = None
        self._control: Callable[[str], str] | None = None
        self._server: uvicorn.Server | None = None
        self._thread: threading.Thread | None = None
        self.error: BaseException | None = None

    # ---- the simulator's side (its thread): one append each ----

    def tap(self, direction: str, data: bytes) -> None:
        """``on_traffic``: bytes the simulator read (``host``) or wrote (``device``)."""
        self._inbox.append(("bytes", time.time(), direction, data))

    def fact(self, fact: Fact) -> None:
        """``ControlChannel.on_fact``: what a control command did that the line cannot show."""
        self._inbox.append(fact)

    # ---- running ----

    def start(self, sim: RunningSim, control: Callable[[str], str]) -> None:
        """Serve the panel of ``sim`` (``control``: the control channel) in a thread of its own."""
        self._sim, self._control = sim, control
        app = Starlette(routes=[
            Route("/", self._page), Route("/api/state", self._get_state), Route("/api/line", self._get_line),
            Route("/api/control", self._post_control, methods=["POST"]), Route("/api/feed", self._feed),
        ])
        config = uvicorn.Config(app, log_config=None, access_log=False, lifespan="off", log_level="warning",
                                timeout_graceful_shutdown=1)
        self._server = uvicorn.Server(config)
        self._thread = threading.Thread(target=self._run, name="xac1-panel", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            asyncio.run(self._serve())
        except BaseException as exc:  # said by the owner
            self.error = exc

    async def _serve(self) -> None:
        assert self._server is not None
        pump = asyncio.create_task(self._pump())
        try:
            await self._server.serve(sockets=[self._socket])
        finally:
            pump.cancel()

    def close(self) -> None:
        """Stop serving (live feeds end), and wait for the thread."""
        if self._server is not None:
            self._server.should_exit = True
        if self._thread is not None:
            self._thread.join(STOP_WAIT_S)
        self._socket.close()

    async def _pump(self) -> None:
        assert self._server is not None
        while not self._server.should_exit:
            await asyncio.sleep(POLL_S)
            self._step()
        for queue in self._listeners:
            queue.put_nowait(None)  # the feeds end, so the server stops at once

    def _step(self) -> None:
        """The inbox to the history (and to the engine while someone looks); what changed to the
        listeners."""
        inbox, watch = self._inbox, self._watch
        while inbox:
            item = inbox.popleft()
            self._history.append(item)
            if watch is not None:
                _judge(watch, item)
        if not self._listeners:
            self._watch = None  # no one looks: the engine rests
            return
        watch = self.watch()
        state = self.state()
        if state != self._state:
            self._state = state
            self._send(_sse("state", state))
        if watch.seen != self._sent:
            self._send(_sse("line", watch.rows(self._sent)))
            self._sent = watch.seen

    @property
    def judging(self) -> bool:
        """Is the engine judging the line now (only while someone looks)?"""
        return self._watch is not None

    def watch(self) -> LineWatch:
        """The line judged up to now: the history judged from its first host line (the facts before it
        too), when no one looked."""
        if self._watch is None:
            self._watch, self._sent = LineWatch(), 0
            host_seen = False
            for item in self._history:
                host_seen = host_seen or item[:1] == ("bytes",) and item[2] == "host"
                if host_seen or item[0] != "bytes":  # an answer whose command is gone is left out
                    _judge(self._watch, item)
        self._watch.tick(time.time())
        return self._watch

    def _send(self, message: str) -> None:
        for queue in self._listeners:
            queue.put_nowait(message)

    def state(self) -> dict[str, Any]:
        assert self._sim is not None
        with self._sim.lock:
            return state_of(self._sim.model, time.monotonic())

    # ---- the routes ----

    async def _page(self, request: Request) -> Response:
        page = resources.files(__package__).joinpath("page.html").read_text(encoding="utf-8")
        return HTMLResponse(page, headers={"Cache-Control": "no-store"})

    async def _get_state(self, request: Request) -> Response:
        return JSONResponse(self.state())

    async def _get_line(self, request: Request) -> Response:
        self._step()
        return JSONResponse(self.watch().rows())

    async def _post_control(self, request: Request) -> Response:
        assert self._control is not None
        origin = request.headers.get("origin")
        if origin is not None and origin != f"{request.url.scheme}://{request.headers.get('host')}":
            error = (f"a page of {origin} may not control the simulator (only the panel's own page, or a "
                     "client that sends no Origin)")
            return JSONResponse({"ok": False, "command": "", "error": error}, status_code=403)
        command = (await request.body()).decode("utf-8", "replace").strip()
        if len(command) > MAX_COMMAND or "\n" in command:
            return JSONResponse({"ok": False, "command": command[:MAX_COMMAND],
                                 "error": f"one control command of at most {MAX_COMMAND} characters"},
                                status_code=400)
        try:
            result = self._control(command)
        except ValueError as exc:
            return JSONResponse({"ok": False, "command": command, "error": str(exc)}, status_code=400)
        self._step()
        return JSONResponse({"ok": True, "command": command, "result": result})

    async def _feed(self, request: Request) -> Response:
        queue: asyncio.Queue[str | None] = asyncio.Queue()
        self._step()
        watch = self.watch()
        first = _sse("state", self.state()) + _sse("line", watch.rows())
        self._listeners.add(queue)
        self._sent = watch.seen

        async def stream() -> AsyncIterator[str]:
            try:
                yield first
                while (message := await queue.get()) is not None:
                    yield message
            finally:
                self._listeners.discard(queue)

        return StreamingResponse(stream(), media_type="text/event-stream",
                                 headers={"Cache-Control": "no-store"})


@contextlib.contextmanager
def panel_for(sim: RunningSim, panel: Panel, control: Callable[[str], str]) -> Iterator[Panel]:
    """``panel`` serving ``sim`` for the ``with`` block, closed after it."""
    panel.start(sim, control)
    try:
        yield panel
    finally:
        panel.close()
