"""The studio server without a browser: the command's interface, security, recompiling, exports."""
from __future__ import annotations

import json
import shutil
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("starlette")
pytest.importorskip("uvicorn")
pytest.importorskip("watchfiles")

from shapedisplay.errors import InputError, ShapeDisplayError  # noqa: E402
from shapedisplay.author.scene import compile_scene  # noqa: E402
from shapedisplay.studio.lines import error_line  # noqa: E402
from shapedisplay.studio.server import check_host  # noqa: E402
from shapedisplay.table.model import FrictionTable  # noqa: E402

from studio_helpers import PHONE, StudioProcess  # noqa: E402


@pytest.fixture(scope="module")
def studio(tmp_path_factory):
    d = tmp_path_factory.mktemp("scene")
    shutil.copy(PHONE, d / "phone.toml")
    s = StudioProcess(d / "phone.toml")
    s.folder = d
    s.wait_state(lambda st: st["table_generation"] is not None)
    yield s
    s.stop()


def test_prints_url_serves_page_and_table_only_with_token(studio):
    status, body = studio.get("/")
    assert status == 200 and b"shapedisplay studio" in body and studio.token.encode() in body
    assert studio.get("/", token=False)[0] == 403
    assert studio.get("/api/table", token=False)[0] == 403
    status, body = studio.get("/api/table")
    assert status == 200
    table = FrictionTable.from_bytes(body, "studio table")
    assert table.checksum == compile_scene(studio.folder / "phone.toml").table.checksum


def test_wrong_token_and_every_route_refused_without_it(studio):
    for path in ("/static/studio.js", "/static/worklet.js", "/api/state", "/api/runtime.wasm", "/api/runtime",
                 "/api/map.png", "/api/scene", "/api/export/json", "/static/design.js", "/api/schema"):
        assert studio.get(path, token=False)[0] == 403, path
        assert studio.get(path + "?token=" + "x" * len(studio.token), token=False)[0] == 403, path
    scene = studio.folder / "phone.toml"
    before = scene.read_bytes()
    for path in ("/api/edit", "/api/check", "/api/undo", "/api/redo", "/api/revert", "/api/resolve", "/api/pin",
                 "/api/export-ahap"):
        body = b'{"base": "x", "ops": [{"op": "delete", "widget": "home"}], "choice": "mine", "mine": ""}'
        assert studio.get(path, token=False, method="POST", data=body)[0] == 403, path
        assert studio.get(path, method="POST", data=body, headers={"Origin": "http://attacker.example"})[0] == 403
        assert studio.get(path, method="POST", data=body, headers={"Host": "rebind.example:80"})[0] == 403
    assert scene.read_bytes() == before


def test_foreign_host_or_origin_refused(studio):
    assert studio.get("/", headers={"Host": "attacker.example:80"})[0] == 403
    port = studio.host.split(":")[1]
    assert studio.get("/", headers={"Host": f"rebind.example:{port}"})[0] == 403
    assert studio.get("/api/state", headers={"Origin": "http://attacker.example"})[0] == 403
    assert studio.get("/api/state", headers={"Origin": f"http://{studio.host}"})[0] == 200
    assert studio.get("/api/state", headers={"Host": f"localhost:{port}"})[0] == 200


def test_websocket_needs_token_and_own_origin(studio):
    from websockets.exceptions import InvalidStatus, ConnectionClosedError
    from websockets.sync.client import connect
    own = f"http://{studio.host}"
    with connect(f"ws://{studio.host}/ws?token={studio.token}", origin=own) as ws:
        msg = json.loads(ws.recv(timeout=10))
        assert msg["type"] == "state" and msg["state"]["source"] == "phone.toml"
    for url, origin in ((f"ws://{studio.host}/ws", own),
                        (f"ws://{studio.host}/ws?token={studio.token}", "http://attacker.example"),
                        (f"ws://{studio.host}/ws?token={studio.token}", None)):
        with pytest.raises((InvalidStatus, ConnectionClosedError, OSError)):
            with connect(url, origin=origin) as ws:
                ws.recv(timeout=5)


def test_runtime_gets_the_tables_binary_image(studio):
    from shapedisplay.render.image import read_image
    status, body = studio.get("/api/runtime")
    assert status == 200
    n = int.from_bytes(body[:4], "little")
    layout = json.loads(body[4:4 + n])
    image = body[4 + n:]
    table = FrictionTable.from_bytes(studio.get("/api/table")[1])
    assert len(image) == layout["bytes"] and read_image(image).checksum == table.checksum
    assert sorted(c["name"] for c in layout["channels"]) == table.channels
    assert layout["tick_rate"] == 10000.0 and layout["audio_rate"] == 48000.0 and layout["model"] == "exact"


def test_runtime_sends_each_offered_models_pad_parameters(studio):
    """Every model the page offers comes with its whole PAD_PARAMS block as the Python model derives it."""
    import base64

    from shapedisplay.render import Renderer
    from shapedisplay.render.layouts import PAD_PARAMS
    from shapedisplay.render.models import MODEL_IDS, get_model
    from shapedisplay.render.native import C_MODELS
    status, body = studio.get("/api/runtime")
    n = int.from_bytes(body[:4], "little")
    layout = json.loads(body[4:4 + n])                       # plain JSON: no Infinity or NaN tokens
    assert layout["pad_fields"] == list(PAD_PARAMS.names)
    assert list(layout["models"]) == list(C_MODELS)
    table = FrictionTable.from_bytes(studio.get("/api/table")[1])
    device = Renderer(table).device
    for name, entry in layout["models"].items():
        assert entry["id"] == MODEL_IDS[name] and "error" not in entry
        block = np.frombuffer(base64.b64decode(entry["pad"]), "<f8")
        want = get_model(name, device).params
        assert block.tolist() == [float(want[f]) for f in PAD_PARAMS.names], name
    blocks = {m: np.frombuffer(base64.b64decode(e["pad"]), "<f8") for m, e in layout["models"].items()}
    k = PAD_PARAMS.names.index("karnopp_spring")
    assert blocks["karnopp"][k] > 0 and blocks["exact"][k] == 0
    assert np.isinf(blocks["stribeck"][PAD_PARAMS.names.index("substep")])      # why the blocks are not JSON
    assert studio.wait_state(lambda st: True)["runtime"]["models"] == list(C_MODELS)


def test_wasm_module_has_no_imports(studio):
    status, body = studio.get("/api/runtime.wasm")
    assert status == 200 and body[:4] == b"\0asm"
    # import section (id 2) absent: the module needs nothing from the page
    pos, sections = 8, []
    while pos < len(body):
        sid = body[pos]
        pos += 1
        size = shift = 0
        while True:
            b = body[pos]
            pos += 1
            size |= (b & 0x7F) << shift
            shift += 7
            if not b & 0x80:
                break
        sections.append(sid)
        pos += size
    assert 2 not in sections and 7 in sections      # no imports; exports present


def test_editing_recompiles_and_an_error_keeps_the_last_table(studio):
    scene = studio.folder / "phone.toml"
    good = scene.read_text()
    st0 = studio.wait_state(lambda st: st["error"] is None)
    try:
        scene.write_text(good.replace('level = 3 ', 'level = 4 '))
        st1 = studio.wait_state(lambda st: st["table_generation"] > st0["table_generation"])
        assert st1["checksum"] != st0["checksum"] and st1["error"] is None
        bad = good.replace('size = "36x16 mm"', 'size = "36x16 furlong"')
        scene.write_text(bad)
        st2 = studio.wait_state(lambda st: st["error"] is not None)
        line = next(i for i, t in enumerate(bad.splitlines(), 1) if "furlong" in t)
        assert st2["error"]["line"] == line and "furlong" in st2["error"]["message"]
        assert st2["table_generation"] == st1["table_generation"] and st2["checksum"] == st1["checksum"]
        assert studio.get("/api/table")[0] == 200                    # the last good table is still served
    finally:
        scene.write_text(good)
        studio.wait_state(lambda st: st["error"] is None and st["table_generation"] > st0["table_generation"])


def test_save_from_page_writes_the_scene_and_exports_go_to_the_output_folder(studio):
    scene = studio.folder / "phone.toml"
    text = scene.read_text()
    from shapedisplay.studio.edits import version_of
    assert studio.get("/api/scene", method="PUT", data=text.encode())[0] == 400     # no version: refused
    status, _ = studio.get("/api/scene", method="PUT", data=text.encode(),
                           headers={"X-Scene-Base": version_of(text.encode())})
    assert status == 200 and scene.read_text() == text
    out = studio.folder / "studio-out"
    status, body = studio.get("/api/export/c")
    assert status == 200 and b"#define" in body and (out / "phone.h").read_bytes() == body
    status, body = studio.get("/api/export/table")
    assert status == 200 and (out / "phone.npz").is_file()
    st = json.loads(studio.get("/api/state")[1])
    assert {"table", "json", "c", "bin"} <= set(st["export_formats"])
    for fmt in st["export_formats"]:                       # every format the library exports, as buttons
        assert studio.get(f"/api/export/{fmt}")[0] == 200, fmt
    from shapedisplay.render.image import read_image
    assert read_image((out / "phone.bin").read_bytes()).checksum == \
        FrictionTable.load(out / "phone.npz").checksum
    assert studio.get("/api/export/../../etc")[0] in (400, 404)
    assert studio.get("/api/export/nope")[0] == 400
    before = sorted(p.name for p in studio.folder.iterdir())
    assert studio.get("/api/map.png?channel=grad_x")[0] == 200
    assert studio.get("/api/map.png?channel=lateral_x")[0] == 400       # not stored: an error, not a picture
    assert sorted(p.name for p in studio.folder.iterdir()) == before


def test_scene_reading_outside_its_folder_is_refused(tmp_path):
    secret = tmp_path / "secret.png"
    secret.write_bytes(b"\x89PNG")
    d = tmp_path / "scene"
    d.mkdir()
    (d / "s.toml").write_text('[canvas]\nsize = "20x20 mm"\nresolution = "1 mm"\n\n[[widget]]\nid = "m"\n'
                              'type = "image"\nfile = "../secret.png"\nposition = "0,0 mm"\nsize = "20x20 mm"\n'
                              'height = "0:1 mm"\n')
    s = StudioProcess(d / "s.toml")
    try:
        st = s.wait_state(lambda st: st["error"] is not None)
        assert "outside the scene's folder" in st["error"]["message"] and st["error"]["line"] == 8
        assert st["table_generation"] is None
        assert s.get("/api/table")[0] == 409
    finally:
        s.stop()


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "shapedisplay", "studio", *args], capture_output=True, text=True,
                          timeout=60)


def test_cli_refusals_are_one_line(tmp_path):
    r = _cli(str(PHONE), "--no-browser", "--host", "0.0.0.0")
    assert r.returncode == 2 and "--allow-remote" in r.stderr and "Traceback" not in r.stderr
    r = _cli(str(PHONE), "--no-browser", "--device", str(tmp_path / "dev.toml"))
    assert r.returncode == 2 and "outside the source's folder" in r.stderr
    r = _cli(str(tmp_path / "missing.toml"), "--no-browser")
    assert r.returncode == 2 and "no such file" in r.stderr
    r = _cli(str(PHONE), "--no-browser", "--size", "10x10mm")
    assert r.returncode == 2 and "--size" in r.stderr
    r = _cli(str(PHONE), "--no-browser", "--model", "tanh")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "`--model` must be one of exact, jump, karnopp, stribeck" in r.stderr and "tanh" in r.stderr


def test_check_host():
    assert check_host("127.0.0.1", False) == "127.0.0.1"
    assert check_host("::1", False) == "::1"
    with pytest.raises(InputError, match="--allow-remote"):
        check_host("192.168.1.5", False)
    assert check_host("192.168.1.5", True) == "192.168.1.5"
    with pytest.raises(InputError, match="IP address"):
        check_host("example.com", True)


def test_ctrl_c_stops_cleanly(tmp_path):
    shutil.copy(PHONE, tmp_path / "phone.toml")
    s = StudioProcess(tmp_path / "phone.toml")
    s.wait_state(lambda st: st["table_generation"] is not None)
    rc = s.stop()
    err = s.proc.stderr.read()
    assert rc == 0 and "Traceback" not in err
    assert any("stopped" in line for line in s.lines)


@pytest.mark.parametrize("old,new,needle", [
    ('size = "20x20 mm"', 'size = "20x20 parsec"', "parsec"),                 # widget field
    ("level = 3 ", "level = 9 ", "level = 9"),                                # widget field from [defaults.button]
    ('resolution = "0.5 mm"', 'resolution = "0.5"', 'resolution = "0.5"'),   # [canvas] field
    ('n_base = "1 N"', 'n_base = "1 N" "', 'n_base = "1 N" "'),                # TOML syntax
    ('type = "dent"', 'type = "dentt"', "dentt"),                             # widget type
    ("levels = 5", "levels = -5", "levels = -5"),                             # [defaults]
])
def test_error_line_points_at_the_field(tmp_path, old, new, needle):
    text = PHONE.read_text().replace(old, new, 1)
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(ShapeDisplayError) as exc:
        compile_scene(p)
    line = error_line(text, str(exc.value))
    assert needle in text.splitlines()[line - 1]


def test_a_file_the_scene_references_recompiles_it(tmp_path):
    from PIL import Image
    src = PHONE.parent
    shutil.copy(src / "map.toml", tmp_path / "map.toml")
    shutil.copy(src / "terrain.png", tmp_path / "terrain.png")
    s = StudioProcess(tmp_path / "map.toml")
    try:
        st0 = s.wait_state(lambda st: st["table_generation"] is not None, timeout=60)
        img = np.asarray(Image.open(tmp_path / "terrain.png"))
        Image.fromarray((img // 2).astype(img.dtype)).save(tmp_path / "terrain.png")
        st1 = s.wait_state(lambda st: st["table_generation"] > st0["table_generation"], timeout=60)
        assert st1["checksum"] != st0["checksum"] and st1["error"] is None
    finally:
        s.stop()


def test_snapshot_is_the_3d_preview_with_the_stroke(studio):
    pytest.importorskip("pyvista")
    n = 200
    t = np.arange(n) / 1e4
    stroke = {"t": t.tolist(), "x": np.full(n, 0.062).tolist(), "y": np.linspace(0.01, 0.03, n).tolist(),
              "normal_force": np.ones(n).tolist(), "friction_force": np.full(n, 0.3).tolist(),
              "state": [0] * n, "event_time": [0.005], "event_amplitude": [0.1]}
    status, body = studio.get("/api/snapshot", method="POST", data=json.dumps({"stroke": stroke}).encode())
    assert status == 200 and body[:8] == b"\x89PNG\r\n\x1a\n"
    from io import BytesIO

    from PIL import Image
    img = np.asarray(Image.open(BytesIO(body)).convert("RGB"))
    assert img.shape[0] > 100 and img.std() > 10        # a picture, not a blank frame
    status, body = studio.get("/api/snapshot", method="POST", data=b"[1, 2]")
    assert status == 400 and b"JSON object" in body


def test_default_port_taken_moves_to_the_next_free_one():
    """Without --port the studio takes 8765, or the next free port when another program holds it."""
    import socket

    from shapedisplay.studio.server import DEFAULT_PORT, PORT_TRIES, bind_port
    held = socket.socket()
    try:
        held.bind(("127.0.0.1", DEFAULT_PORT))
        held.listen(1)
    except OSError:
        pass                                  # already held by someone else: the same situation
    try:
        sock = bind_port("127.0.0.1", None)
        try:
            port = sock.getsockname()[1]
            assert DEFAULT_PORT < port < DEFAULT_PORT + PORT_TRIES
        finally:
            sock.close()
        with pytest.raises(ShapeDisplayError, match="`--port` 8765: cannot listen"):
            bind_port("127.0.0.1", DEFAULT_PORT)
    finally:
        held.close()


def _raw_get(studio, path: str, headers: list) -> int:
    """Status of a GET sent with exactly ``headers`` (repeats kept; urllib would merge them)."""
    import http.client
    conn = http.client.HTTPConnection(studio.host, timeout=30)
    try:
        conn.putrequest("GET", f"{path}?token={studio.token}", skip_host=True, skip_accept_encoding=True)
        for name, value in headers:
            conn.putheader(name, value)
        conn.endheaders()
        return conn.getresponse().status
    finally:
        conn.close()


def _gate_status(headers: list) -> int:
    """Status the studio's security gate answers a request with ``headers`` (in-process, ASGI)."""
    import asyncio

    from shapedisplay.studio.app import Gate

    async def app(scope, receive, send):
        await send({"type": "http.response.start", "status": 200, "headers": []})
        await send({"type": "http.response.body", "body": b""})

    sent = []

    async def send(msg):
        sent.append(msg)

    async def receive():
        return {"type": "http.request", "body": b""}

    scope = {"type": "http", "query_string": b"token=t", "path": "/api/state",
             "headers": [(k.lower().encode(), v.encode()) for k, v in headers]}
    asyncio.run(Gate(app, "t", {"h:1"}, {"http://h:1"})(scope, receive, send))
    return sent[0]["status"]


def test_two_host_or_two_origin_headers_are_refused(studio):
    assert _gate_status([("Host", "h:1")]) == 200
    assert _gate_status([("Host", "h:1"), ("Origin", "http://h:1")]) == 200
    assert _gate_status([("Host", "h:1"), ("Host", "h:1")]) == 403
    assert _gate_status([("Host", "evil:1"), ("Host", "h:1")]) == 403
    assert _gate_status([("Host", "h:1"), ("Origin", "http://evil"), ("Origin", "http://h:1")]) == 403
    assert _gate_status([("Host", "h:1"), ("Origin", "http://h:1"), ("Origin", "http://h:1")]) == 403
    # through the real server: the HTTP parser may refuse two Hosts itself (400) before the gate does (403)
    own_host, own_origin = studio.host, f"http://{studio.host}"
    assert _raw_get(studio, "/api/state", [("Host", own_host)]) == 200
    assert _raw_get(studio, "/api/state", [("Host", own_host), ("Origin", own_origin)]) == 200
    assert _raw_get(studio, "/api/state", [("Host", own_host), ("Host", own_host)]) in (400, 403)
    assert _raw_get(studio, "/api/state", [("Host", own_host), ("Host", "attacker.example")]) in (400, 403)
    assert _raw_get(studio, "/api/state", [("Host", own_host), ("Origin", own_origin),
                                           ("Origin", own_origin)]) == 403
    assert _raw_get(studio, "/api/state", [("Host", own_host), ("Origin", "http://attacker.example"),
                                           ("Origin", own_origin)]) == 403


def test_malformed_snapshot_bodies_are_400_with_one_line(tmp_path):
    shutil.copy(PHONE, tmp_path / "phone.toml")
    s = StudioProcess(tmp_path / "phone.toml")
    try:
        s.wait_state(lambda st: st["table_generation"] is not None)
        for body in (b'{"stroke":{"t":{"a":1}}}', b'{"stroke":{"t":[[1]]}}', b'{"stroke":{"t":["a"]}}',
                     b'{"stroke":{"t":[true]}}', b'{"stroke":{"nope":[1]}}', b'{"stroke":[1]}',
                     b'{"channel":{"a":1}}', b"[" * 100_000 + b"]" * 100_000,
                     b'{"a":' * 50_000 + b"1" + b"}" * 50_000, b"{not json", b"\xff\xfe"):
            status, reply = s.get("/api/snapshot", method="POST", data=body)
            assert status == 400, (body[:40], status, reply[:200])
            msg = json.loads(reply)["error"]
            assert msg and "\n" not in msg, msg
    finally:
        s.stop()
    err = s.proc.stderr.read()
    assert "Traceback" not in err and "500" not in err, err[-2000:]
