"""The live pages: tornado HTTP + WebSocket on loopback (by default), serving the static therapist and patient
pages (package data in ``pipeline/live/static``) and pushing new frames, events and figures every
``1 / fps`` s to each connected page (all frames since the last push: the page draws at ``fps``, the
computation never skips a sample)."""
from __future__ import annotations

import asyncio
import json
import math
import threading
import time
from pathlib import Path

import numpy as np

import tornado.httpserver
import tornado.ioloop
import tornado.web
import tornado.websocket

STATIC = Path(__file__).with_name("static")


def _clean(o):
    if isinstance(o, float):
        return o if math.isfinite(o) else None
    if isinstance(o, dict):
        return {k: _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    if hasattr(o, "item"):
        return _clean(o.item())
    return o


class _Ws(tornado.websocket.WebSocketHandler):
    def initialize(self, server):
        self.srv = server
        self.seq = 0
        self.eid = 0                       # the hub's recent events go with the next event message

    def open(self):
        self.srv.clients.add(self)
        self.write_message(json.dumps(_clean({"type": "config", **self.srv.config})))

    def on_close(self):
        self.srv.clients.discard(self)

    def check_origin(self, origin):          # pages come from this server only (any of its addresses on --host 0.0.0.0)
        netloc = origin.split("://", 1)[-1].split("/")[0]
        if self.srv.host in ("0.0.0.0", "::", ""):
            return netloc.rsplit(":", 1)[-1] == str(self.srv.port)
        return netloc in self.srv.origins


class _State(tornado.web.RequestHandler):
    def initialize(self, server):
        self.srv = server

    def get(self):
        fr, ev, st = self.srv.hub.since(0, limit=1)
        self.set_header("Content-Type", "application/json")
        self.write(json.dumps(_clean({**st, "frames": self.srv.hub.seq, "last_frame": fr[-1] if fr else None,
                                      "events": len(self.srv.hub.events), "summary": self.srv.summary()})))


class LiveServer:
    """Serve ``hub`` (:class:`stridelab.pipeline.live.session.Hub`) on ``host:port`` in a background thread.

    config: sent to each page on connect (normative bands, cue measure and range, participant)."""

    def __init__(self, hub, *, host: str = "127.0.0.1", port: int = 8765, fps: float = 30.0, config: dict | None = None,
                 summary=None):
        self.hub, self.host, self.port, self.fps = hub, host, int(port), float(fps)
        self.config = config or {}
        self.summary = summary or (lambda: {})
        self.clients: set = set()
        from stridelab.pipeline.live.session import LatencyStats
        self.delivery = LatencyStats()      # event sample arrival -> event sent to the pages
        self.origins = {f"{host}:{port}", f"localhost:{port}", f"127.0.0.1:{port}"}
        self._loop = None
        self._ready = threading.Event()
        self._thread = threading.Thread(target=self._run, name="live-server", daemon=True)
        self.error = None

    def start(self) -> None:
        self._thread.start()
        self._ready.wait(10)
        if self.error:
            raise ValueError(f"cannot serve the live page on {self.host}:{self.port}: {self.error}; "
                             f"choose another --port")

    def stop(self) -> None:
        if self._loop is not None:
            self._loop.add_callback(self._loop.stop)
        self._thread.join(5)

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}/"

    def _run(self) -> None:
        asyncio.set_event_loop(asyncio.new_event_loop())
        app = tornado.web.Application([
            (r"/", tornado.web.RedirectHandler, {"url": "/therapist.html"}),
            (r"/patient", tornado.web.RedirectHandler, {"url": "/patient.html"}),
            (r"/ws", _Ws, {"server": self}),
            (r"/api/state", _State, {"server": self}),
            (r"/(.*)", tornado.web.StaticFileHandler, {"path": str(STATIC)}),
        ])
        try:
            srv = tornado.httpserver.HTTPServer(app)
            srv.listen(self.port, address=self.host)
            if self.port == 0:
                self.port = next(iter(srv._sockets.values())).getsockname()[1]
                self.origins |= {f"{self.host}:{self.port}", f"localhost:{self.port}", f"127.0.0.1:{self.port}"}
        except OSError as e:
            self.error = e.strerror
            self._ready.set()
            return
        self._loop = tornado.ioloop.IOLoop.current()
        tornado.ioloop.PeriodicCallback(self._push, 1000.0 / self.fps).start()
        loop = self._loop
        self.hub.listeners.append(lambda: loop.add_callback(self._push_events))
        self._ready.set()
        self._loop.start()
        srv.stop()

    def _push_events(self) -> None:
        """New gait events to every page as soon as the computing thread published them (not at the next frame
        tick: up to 1/fps later); ``delivery`` times each event from its sample's arrival to this send."""
        first = True
        for c in list(self.clients):
            ev = self.hub.events_after(c.eid)
            if not ev:
                continue
            c.eid = ev[-1]["eid"]
            try:
                c.write_message(json.dumps(_clean({"type": "events", "events": ev})))
            except tornado.websocket.WebSocketClosedError:
                self.clients.discard(c)
                continue
            if first:
                now = time.perf_counter_ns()
                self.delivery.add(np.array([now - e["arrival_ns"] for e in ev if e.get("arrival_ns", 0) > 0],
                                           np.int64))
                first = False

    def _push(self) -> None:
        for c in list(self.clients):
            fr, _ev, st = self.hub.since(c.seq)
            if not fr:
                continue
            c.seq = fr[-1][0] + 1
            msg = {"type": "frames", "frames": [[f[1], f[2], f[3], f[4]] for f in fr], "events": [],
                   "metrics": st.get("metrics", {}), "speed": st.get("speed"), "summary": self.summary()}
            try:
                c.write_message(json.dumps(_clean(msg)))
            except tornado.websocket.WebSocketClosedError:
                self.clients.discard(c)
