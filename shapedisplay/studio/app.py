"""The studio's web app: Starlette routes, the security gate, file watching and live updates.

Security (the page can make a sound card drive a tactor, and it edits files):

* it binds to 127.0.0.1 unless told otherwise (:func:`serve`);
* every request and WebSocket must carry the session's random token
  (``?token=...`` or the ``X-Studio-Token`` header), compared in constant time;
* a request whose ``Host`` is not the studio's own address, or whose
  ``Origin`` (when sent) is not the studio's own origin, is refused: a page
  on another site, or a DNS-rebinding name pointing at 127.0.0.1, gets 403;
* files are read only under the source's folder (see :mod:`~shapedisplay.studio.session`) and
  written only to the scene file being edited and under the output folder.

Routes (all under the token):
``GET /`` the page; ``GET /static/NAME`` its scripts; ``GET /api/state`` what
the page shows (JSON); ``GET /api/table`` the current table (.npz bytes);
``GET /api/runtime.wasm`` the C runtime as WebAssembly (``/static/sd_wasm.js``
its wrapper); ``GET /api/runtime``
the current table's binary image for it (with a JSON head); ``GET /api/map.png?channel=NAME`` the top
view; ``GET/PUT /api/scene`` the scene text; ``GET /api/export/FORMAT``;
``POST /api/snapshot`` the 3D preview; ``POST /api/export-ahap`` the AHAP of the page's last stroke;
``WS /ws`` a message per compile (a new table's runtime image first, as a binary message).
Design (scenes; each change names the version of the file it was made on, a
stale one is answered 409 with the disk's text, see :mod:`~shapedisplay.studio.scenefile`):
``POST /api/edit`` canvas, inspector and palette operations; ``POST /api/check`` the same, validated
only; ``POST /api/undo``, ``/api/redo``, ``/api/revert``, ``/api/resolve``; ``GET /api/schema`` the
inspector's keys; ``POST /api/pin`` pins the current table as A (``GET /api/runtime?table=a`` plays it).
"""
from __future__ import annotations

import asyncio
import json
import re
import secrets
import struct
import time
from pathlib import Path
from urllib.parse import parse_qs

from shapedisplay.errors import InputError, ShapeDisplayError

WEB = Path(__file__).resolve().parent / "web"
#: Files served under /static/ (nothing else from disk is ever served).
STATIC = {"studio.js": "text/javascript", "worklet.js": "text/javascript", "studio.css": "text/css",
          "sd_wasm.js": "text/javascript", "design.js": "text/javascript", "reactions.js": "text/javascript"}
#: Largest request body accepted (scene text, a recorded stroke for the snapshot), bytes.
MAX_BODY = 64 << 20


class Gate:
    """ASGI middleware: token, Host and Origin checks on every request and WebSocket."""

    def __init__(self, app, token: str, hosts: set, origins: set):
        self.app, self.token, self.hosts, self.origins = app, token, hosts, origins

    def refusal(self, scope) -> str | None:
        raw = [(k.decode("latin-1").lower(), v.decode("latin-1")) for k, v in scope.get("headers", [])]
        for name in ("host", "origin"):
            if sum(1 for k, _ in raw if k == name) > 1:
                return f"refused: more than one {name.capitalize()} header"
        headers = dict(raw)
        host = headers.get("host", "")
        if host not in self.hosts:
            return f"refused: Host '{host}' is not this studio's address"
        origin = headers.get("origin")
        if origin is not None and origin not in self.origins:
            return f"refused: Origin '{origin}' is not this studio's page"
        if scope["type"] == "websocket" and origin is None:
            return "refused: a WebSocket must come from the studio's page (no Origin)"
        query = parse_qs(scope.get("query_string", b"").decode("latin-1"))
        given = (query.get("token") or [headers.get("x-studio-token", "")])[0]
        if not secrets.compare_digest(given.encode(), self.token.encode()):
            return "refused: missing or wrong token (open the URL the studio printed)"
        return None

    async def __call__(self, scope, receive, send):
        if scope["type"] not in ("http", "websocket"):
            return await self.app(scope, receive, send)
        why = self.refusal(scope)
        if why is None:
            return await self.app(scope, receive, send)
        if scope["type"] == "websocket":
            await receive()                           # websocket.connect
            await send({"type": "websocket.close", "code": 1008, "reason": why[:120]})
            return
        body = why.encode()
        await send({"type": "http.response.start", "status": 403,
                    "headers": [(b"content-type", b"text/plain; charset=utf-8"),
                                (b"content-length", str(len(body)).encode())]})
        await send({"type": "http.response.body", "body": body})


class Studio:
    """The running studio: a session, its clients and the watcher task."""

    def __init__(self, session, model: str = "exact"):
        self.session = session
        self.model = model
        self.clients: set = set()
        self.prepared: dict | None = None       # what the page fetches for the current table
        self.last_change: dict = {}
        self.scenefile = None                   # the scene file's edits and history (scenes only)
        if session.kind == "scene":
            from shapedisplay.studio.scenefile import SceneFile
            self.scenefile = SceneFile(session.source, session.out_dir,
                                       device=session._device if session.device else None)
        self.compiled_version: str | None = None   # the scene bytes the current compile read
        self.last_state: dict | None = None     # the state last broadcast
        self.pushed_generation = None           # the table whose runtime image was last sent to the pages
        self.pinned: dict | None = None         # table A: {"table", "layout", "image", "label"}

    # -------------------------------------------------------------- compile + broadcast
    def compile_and_prepare(self, edited: bool = False) -> bool:
        """Compile (in a worker thread) and prepare everything the page will fetch for a new table.

        ``edited``: the studio has just written the scene after validating it; that scene is compiled
        without reading the file again."""
        from shapedisplay.studio.views import channel_range, colour_map_png
        from shapedisplay.studio.wasm import table_payload
        scene = None
        if self.scenefile is not None:
            from shapedisplay.studio.edits import validated, version_of
            try:
                data = self.session.source.read_bytes()
                self.compiled_version = version_of(data)
                scene = validated(data) if edited else None    # the scene the edit has just validated
            except OSError:
                self.compiled_version = None
        if not self.session.compile(scene):
            return False
        cur = self.session.current
        lay, image = table_payload(cur.table, self.model)
        lay["generation"] = cur.generation
        lay["checksum"] = cur.checksum
        if self.pinned is None:                  # A is the table as the studio opened the source, until pinned
            self.pinned = {"table": cur.table, "layout": dict(lay, which="A"), "image": image,
                           "label": "as opened", "generation": cur.generation, "checksum": cur.checksum}
        first = "normal_force" if "normal_force" in cur.table.channels else cur.table.channels[0]
        from shapedisplay.exchange.friction_png import bitmap_choices
        self.prepared = {"generation": cur.generation, "layout": lay, "image": image, "table": cur.table,
                         "ranges": {c: channel_range(cur.table, c) for c in cur.table.channels},
                         "friction_png": bitmap_choices(cur.table) if "normal_force" in cur.table.channels else None,
                         "maps": {} if edited else {first: colour_map_png(cur.table, first)}}
        return True

    async def recompile(self, reason: str, edited: bool = False) -> None:
        t0 = time.perf_counter()
        await asyncio.get_running_loop().run_in_executor(None, self.compile_and_prepare, edited)
        self.last_change = {"reason": reason, "compile_ms": (time.perf_counter() - t0) * 1e3}
        await self.broadcast()

    async def broadcast(self) -> None:
        """Send every page the state; a new table's runtime image goes first (a binary message, as
        ``GET /api/runtime`` answers), so that the page swaps it in without asking for it."""
        self.last_state = self.state()
        msg = json.dumps({"type": "state", "state": self.last_state})
        prep = self.prepared
        frame = None
        if prep is not None and prep["generation"] != self.pushed_generation:
            head = json.dumps(prep["layout"]).encode()
            frame = struct.pack("<I", len(head)) + head + prep["image"]
            self.pushed_generation = prep["generation"]
        for ws in list(self.clients):
            try:
                if frame is not None:
                    await ws.send_bytes(frame)
                await ws.send_text(msg)
            except Exception:                      # a closed page: forget it
                self.clients.discard(ws)

    def state(self) -> dict:
        from shapedisplay.studio.exports import OPTIONS as export_options_, formats
        d = self.session.state()
        prep = self.prepared
        if prep is not None:
            lay = prep["layout"]
            d["ranges"] = prep["ranges"]
            d["export_options"] = {f: {k: list(v) for k, v in o.items()} for f, o in export_options_.items()}
            d["friction_png"] = prep["friction_png"]      # what "auto" picks, which quantities are flat
            d["runtime"] = {"tick_rate": lay["tick_rate"], "audio_rate": lay["audio_rate"], "model": self.model,
                            "models": list(lay["models"]), "cursor_gain": lay["cursor_gain"]}
        d["last_change"] = self.last_change
        d["export_formats"] = formats()
        if self.scenefile is not None:
            self._design_state(d)
        return d

    def _design_state(self, d: dict) -> None:
        """The design tool's part of the state: the file's version, history, values, A/B."""
        from shapedisplay.studio.edits import version_of
        from shapedisplay.studio.inspector import canvas_origin, widget_values
        try:
            data = self.session.source.read_bytes()
        except OSError:
            return
        d["scene_version"] = version_of(data)
        d["history"] = self.scenefile.history.listing()
        text = data.decode("utf-8", "replace")
        d["values"], d["origin"] = widget_values(text), canvas_origin(text)
        cur = self.session.current
        if cur is not None:
            m = cur.table.meta.get("mapping") or {}
            d["mapping"] = {"n_base": m.get("n_base"), "n_gain": m.get("n_gain")}
            d["widget_params"] = {w["id"]: w.get("params", {}) for w in (cur.report.get("widgets") or [])
                                  if isinstance(w, dict) and "id" in w}
        if self.pinned is not None and cur is not None:
            from shapedisplay.table.diff import widget_changes
            d["ab"] = {"a_checksum": self.pinned["checksum"], "a_label": self.pinned["label"],
                       "a_generation": self.pinned["generation"], "b_checksum": cur.checksum,
                       "changes": widget_changes(self.pinned["table"], cur.table)}

    def layout(self) -> tuple:
        return self.prepared["layout"], self.prepared["image"]

    def colour_map(self, channel: str) -> bytes:
        from shapedisplay.studio.views import colour_map_png
        prep = self.prepared
        if channel not in prep["maps"]:
            prep["maps"][channel] = colour_map_png(prep["table"], channel)
        return prep["maps"][channel]

    async def watch(self, stop: asyncio.Event) -> None:
        """Recompile whenever a file under the source's folder changes (not the output folder)."""
        from watchfiles import awatch
        async for changes in awatch(self.session.root, stop_event=stop, step=20, debounce=400,
                                    watch_filter=lambda _change, path: self.session.watch_filter(path)):
            names = sorted({Path(p).name for _c, p in changes})
            if self.scenefile is not None:
                paths = {Path(p).resolve() for _c, p in changes}
                if paths == {self.session.source}:
                    from shapedisplay.studio.edits import version_of
                    try:
                        if version_of(self.session.source.read_bytes()) == self.compiled_version:
                            continue                # the studio's own write, compiled already
                    except OSError:
                        pass
                self.scenefile.sync()
                from shapedisplay.studio.edits import forget_validated
                forget_validated()                  # a file the scene names may have changed
            await self.recompile("changed: " + ", ".join(names))


def build_app(session, token: str, hosts: set, origins: set, model: str = "exact", watch: bool = True):
    """The ASGI app of a studio on ``session`` (wrapped in the security :class:`Gate`)."""
    from contextlib import asynccontextmanager

    from starlette.applications import Starlette
    from starlette.responses import HTMLResponse, JSONResponse, PlainTextResponse, Response
    from starlette.routing import Route, WebSocketRoute
    from starlette.websockets import WebSocketDisconnect

    studio = Studio(session, model)

    def need_table():
        if session.current is None:
            msg = session.error.message if session.error else "nothing compiled yet"
            raise InputError(f"no table: {msg}")
        return session.current

    def error_response(exc: ShapeDisplayError, status: int = 400):
        return JSONResponse({"error": str(exc)}, status_code=status)

    async def page(request):
        html = (WEB / "index.html").read_text(encoding="utf-8")
        html = html.replace("{{TOKEN}}", token).replace("{{SOURCE}}", _html_escape(session.source.name))
        return HTMLResponse(html, headers={"Cache-Control": "no-store",
                                           "Content-Security-Policy": "default-src 'self'; img-src 'self' blob: data:;"
                                           " script-src 'self' 'wasm-unsafe-eval'; style-src 'self';"
                                           " connect-src 'self' ws: wss:; media-src 'self' blob:"})

    async def static(request):
        name = request.path_params["name"]
        if name not in STATIC:
            return PlainTextResponse("not found", status_code=404)
        from shapedisplay.render.wasm import WRAPPER
        path = WRAPPER if name == "sd_wasm.js" else WEB / name
        body = path.read_text(encoding="utf-8").replace("{{TOKEN}}", token)   # module imports carry the token
        return Response(body, media_type=STATIC[name], headers={"Cache-Control": "no-store"})

    async def state(request):
        return JSONResponse(studio.state())

    async def table(request):
        try:
            cur = need_table()
        except ShapeDisplayError as exc:
            return error_response(exc, 409)
        data = await asyncio.get_running_loop().run_in_executor(None, cur.data)
        return Response(data, media_type="application/octet-stream",
                        headers={"Content-Disposition": f'attachment; filename="{session.source.stem}.npz"'})

    async def runtime_wasm(request):
        from shapedisplay.studio.wasm import module_bytes
        loop = asyncio.get_running_loop()
        try:
            data = await loop.run_in_executor(None, module_bytes)
        except ShapeDisplayError as exc:
            return error_response(exc, 500)
        return Response(data, media_type="application/wasm")

    async def runtime(request):
        try:
            need_table()
            lay, payload = studio.layout()
            if request.query_params.get("table") == "a" and studio.pinned is not None:
                lay, payload = studio.pinned["layout"], studio.pinned["image"]
        except ShapeDisplayError as exc:
            return error_response(exc, 409)
        head = json.dumps(lay).encode()
        return Response(struct.pack("<I", len(head)) + head + payload, media_type="application/octet-stream")

    async def colour_map(request):
        channel = request.query_params.get("channel", "normal_force")
        try:
            need_table()
            rng = request.query_params.get("range")            # a locked colour scale: "lo:hi" in SI units
            if rng:
                from shapedisplay.studio.views import colour_map_png
                try:
                    lo, hi = (float(v) for v in rng.split(":"))
                except ValueError:
                    raise InputError(f"`range` must be 'lo:hi' (got {rng[:40]!r})") from None
                png = await asyncio.get_running_loop().run_in_executor(
                    None, colour_map_png, session.current.table, channel, (lo, hi))
            else:
                png = await asyncio.get_running_loop().run_in_executor(None, studio.colour_map, channel)
        except ShapeDisplayError as exc:
            return error_response(exc, 400)
        return Response(png, media_type="image/png", headers={"Cache-Control": "no-store"})

    async def scene_get(request):
        try:
            data = session.source.read_bytes() if session.kind == "scene" else None
            if data is None:
                session.source_text()                       # raises: not a scene
            from shapedisplay.studio.edits import version_of
            return PlainTextResponse(data.decode("utf-8"), headers={"X-Scene-Version": version_of(data),
                                                                     "Cache-Control": "no-store"})
        except ShapeDisplayError as exc:
            return error_response(exc)

    async def scene_put(request):
        base = request.headers.get("x-scene-base") or request.query_params.get("base")
        try:
            text = (await _body(request)).decode("utf-8")
        except UnicodeDecodeError:
            return JSONResponse({"error": "scene text must be UTF-8"}, status_code=400)
        except ShapeDisplayError as exc:
            return error_response(exc)
        if studio.scenefile is None:
            return error_response(InputError(f"studio source '{session.source.name}' is a {session.kind}, "
                                             "not a scene: cannot save text"))
        return await design_call(studio.scenefile.save_text, base, text, reason="saved from the page", text=text)

    async def design_call(fn, *args, reason: str, text: str | None = None):
        """Run a scene-file change in a worker thread, recompile if it wrote, answer with the new state."""
        from shapedisplay.studio.scenefile import Conflict
        if studio.scenefile is None:
            return error_response(InputError(f"studio source '{session.source.name}' is a {session.kind}: "
                                             "only a scene is edited in the page"))
        loop = asyncio.get_running_loop()
        try:
            out = await loop.run_in_executor(None, fn, *args)
        except Conflict as exc:
            loop.run_in_executor(None, studio.scenefile.flush)          # a change from outside: a step
            return JSONResponse(exc.payload(), status_code=409)
        except ShapeDisplayError as exc:
            from shapedisplay.studio.lines import error_line
            msg = str(exc)
            line = None
            try:
                line = error_line(text if text is not None else session.source_text(), msg)
            except (ShapeDisplayError, OSError, UnicodeDecodeError):
                pass
            return JSONResponse({"error": msg, "line": line}, status_code=400)
        if out.get("changed"):
            await studio.recompile(reason + (f": {out['label']}" if out.get("label") else ""), edited=True)
            out["state"] = studio.last_state             # what the broadcast has just sent
        else:
            out["state"] = studio.state()
        loop.run_in_executor(None, studio.scenefile.flush)         # to disk, now that the table is on its way
        return JSONResponse(out)

    async def design_json(request) -> dict:
        return _json_object(await _body(request) or b"{}", "request")

    async def edit(request):
        try:
            req = await design_json(request)
        except ShapeDisplayError as exc:
            return error_response(exc)
        label = str(req.get("label") or "edit")[:120]
        return await design_call(studio.scenefile.edit if studio.scenefile else None, req.get("base"),
                                 req.get("ops"), label, reason=label)

    async def check(request):
        """Validate operations without writing: the inspector's live messages (the loader's, as `check`)."""
        from shapedisplay.studio.edits import apply_ops
        try:
            req = await design_json(request)
            if studio.scenefile is None:
                raise InputError("only a scene is edited in the page")
            text = session.source_text()
            await asyncio.get_running_loop().run_in_executor(
                None, apply_ops, text, req.get("ops"), session.source,
                session._device() if session.device else None)
        except ShapeDisplayError as exc:
            return JSONResponse({"error": str(exc)})
        return JSONResponse({"error": None})

    def design_route(name):
        async def handler(request):
            try:
                req = await design_json(request)
            except ShapeDisplayError as exc:
                return error_response(exc)
            sf = studio.scenefile
            if name == "resolve":
                args = (req.get("choice"), req.get("base"), req.get("mine"), req.get("disk_version"))
                fn = sf.resolve if sf else None
            else:
                args = (req.get("base"),)
                fn = getattr(sf, name) if sf else None
            return await design_call(fn, *args, reason=name)
        return handler

    async def schema(request):
        from shapedisplay.studio.edits import NEW_WIDGET
        from shapedisplay.studio.inspector import schema as keys
        return JSONResponse({"types": keys(), "palette": list(NEW_WIDGET)})

    async def pin(request):
        try:
            cur = need_table()
        except ShapeDisplayError as exc:
            return error_response(exc, 409)
        lay, image = studio.layout()
        studio.pinned = {"table": cur.table, "layout": dict(lay, which="A"), "image": image,
                         "label": "pinned", "generation": cur.generation, "checksum": cur.checksum}
        return JSONResponse({"pinned": cur.checksum, "state": studio.state()})

    async def export(request):
        from shapedisplay.studio.exports import export_bytes
        fmt = request.path_params["fmt"]
        options = {k: v for k, v in request.query_params.items() if k != "token"}
        try:
            cur = need_table()
            name, data = await asyncio.get_running_loop().run_in_executor(
                None, export_bytes, cur.table, fmt, session.out_dir, session.source.stem, options)
        except ShapeDisplayError as exc:
            return error_response(exc)
        return Response(data, media_type="application/octet-stream", headers=export_headers(name, cur))

    def export_headers(name: str, cur) -> dict:
        """Which table an export holds: the current one, or the last good one while the scene has an error."""
        note = f"table {cur.generation}"
        if session.error is not None:
            note += " (the last good one: the scene has an error)"
        return {"Content-Disposition": f'attachment; filename="{name}"', "X-Export-Table": note}

    async def export_ahap(request):
        from shapedisplay.studio.exports import stroke_ahap
        try:
            body = await _body(request)
            cur = need_table()
            stroke = _json_object(body or b"{}", "AHAP stroke")
            name, data = await asyncio.get_running_loop().run_in_executor(
                None, stroke_ahap, cur.table, stroke, session.out_dir, session.source.stem)
        except ShapeDisplayError as exc:
            return JSONResponse({"error": str(exc).splitlines()[0]}, status_code=400)
        return Response(data, media_type="application/json", headers=export_headers(name, cur))

    async def snapshot(request):
        from shapedisplay.studio.views import snapshot_png
        try:
            body = await _body(request)
            cur = need_table()
            req = _json_object(body or b"{}", "snapshot request")
            channel = req.get("channel", "normal_force")
            if not isinstance(channel, str):
                raise InputError(f"snapshot `channel` must be a channel name (got {type(channel).__name__})")
            stroke = req.get("stroke")            # checked by snapshot_png (views.check_stroke)
            png = await asyncio.get_running_loop().run_in_executor(None, snapshot_png, cur.table, channel, stroke)
        except ShapeDisplayError as exc:
            return JSONResponse({"error": str(exc).splitlines()[0]}, status_code=400)
        return Response(png, media_type="image/png")

    async def ws(websocket):
        await websocket.accept()
        studio.clients.add(websocket)
        try:
            await websocket.send_text(json.dumps({"type": "state", "state": studio.state()}))
            while True:
                await websocket.receive_text()         # the page only listens; keeps the socket open
        except WebSocketDisconnect:
            pass
        finally:
            studio.clients.discard(websocket)

    @asynccontextmanager
    async def lifespan(app):
        if studio.scenefile is not None:
            studio.scenefile.sync()            # a change made while the studio was closed is a step too
        await studio.recompile("start")
        stop = asyncio.Event()
        task = asyncio.create_task(studio.watch(stop)) if watch else None
        try:
            yield
        finally:
            stop.set()
            if task is not None:
                task.cancel()
                try:
                    await task
                except (asyncio.CancelledError, Exception):
                    pass

    routes = [
        Route("/", page), Route("/static/{name}", static), Route("/api/state", state), Route("/api/table", table),
        Route("/api/runtime.wasm", runtime_wasm), Route("/api/runtime", runtime),
        Route("/api/map.png", colour_map), Route("/api/scene", scene_get, methods=["GET"]),
        Route("/api/export-ahap", export_ahap, methods=["POST"]),
        Route("/api/scene", scene_put, methods=["PUT"]), Route("/api/export/{fmt}", export),
        Route("/api/snapshot", snapshot, methods=["POST"]), WebSocketRoute("/ws", ws),
        Route("/api/edit", edit, methods=["POST"]), Route("/api/check", check, methods=["POST"]),
        Route("/api/schema", schema), Route("/api/pin", pin, methods=["POST"]),
        *[Route(f"/api/{name}", design_route(name), methods=["POST"]) for name in ("undo", "redo", "revert", "resolve")],
    ]
    app = Starlette(routes=routes, lifespan=lifespan)
    app.state.studio = studio
    return Gate(app, token, hosts, origins)


#: Deepest nesting of arrays and objects in a request body (a stroke: 2), checked before parsing.
MAX_JSON_NESTING = 32
_JSON_TOKENS = re.compile(rb'"(?:[^"\\]|\\.)*"|[\[\]{}]')


def _json_object(body: bytes, what: str) -> dict:
    """Parse a request body that must be a JSON object, nested at most MAX_JSON_NESTING deep."""
    depth = 0
    for m in _JSON_TOKENS.finditer(body):
        tok = m.group()
        if tok in (b"[", b"{"):
            depth += 1
            if depth > MAX_JSON_NESTING:
                raise InputError(f"{what} nests arrays and objects more than {MAX_JSON_NESTING} levels deep")
        elif tok in (b"]", b"}"):
            depth -= 1
    try:
        req = json.loads(body)
    except (ValueError, UnicodeDecodeError) as exc:
        raise InputError(f"{what} must be JSON ({str(exc).splitlines()[0]})") from None
    if not isinstance(req, dict):
        raise InputError(f"{what} must be a JSON object (got {type(req).__name__})")
    return req


async def _body(request) -> bytes:
    size = int(request.headers.get("content-length") or 0)
    if size > MAX_BODY:
        raise InputError(f"request body must be at most {MAX_BODY} bytes (got {size})")
    data = b""
    async for chunk in request.stream():
        data += chunk
        if len(data) > MAX_BODY:
            raise InputError(f"request body must be at most {MAX_BODY} bytes")
    return data


def _html_escape(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;").replace('"', "&quot;")
