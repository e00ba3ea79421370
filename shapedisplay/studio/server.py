"""Start and stop a studio: the socket, the token, the printed URL and Uvicorn."""
from __future__ import annotations

import ipaddress
import secrets
import socket
import sys
from pathlib import Path

from shapedisplay.errors import InputError, require

LOOPBACK = "127.0.0.1"
#: The port the studio listens on unless told otherwise; when it is taken, the next free one of
#: PORT_TRIES ports is used (the printed URL says which).
DEFAULT_PORT = 8765
PORT_TRIES = 20


def check_host(host: str, allow_remote: bool) -> str:
    """The address to bind: loopback always; anything else only with ``allow_remote``."""
    try:
        addr = ipaddress.ip_address(host)
    except ValueError:
        raise InputError(f"`--host` must be an IP address, e.g. 127.0.0.1 (got {host!r})") from None
    if not addr.is_loopback and not allow_remote:
        raise InputError(f"`--host` {host} is not a loopback address: the studio then serves your files and "
                         "drives your sound output for anyone who can reach it and has the URL; "
                         "add --allow-remote to do it anyway")
    return str(addr)


def serve(source, device=None, port: int | None = None, host: str = LOOPBACK, allow_remote: bool = False,
          open_browser: bool = True, out_dir=None, options=None, model: str = "exact",
          out=sys.stdout, err=sys.stderr) -> None:
    """Serve the studio on ``host:port`` until interrupted (Ctrl-C).

    Prints one line with the URL (``http://HOST:PORT/?token=TOKEN``) once the
    socket listens; ``port=None`` takes DEFAULT_PORT or the next free port after it,
    ``port=0`` any free port.
    """
    require("starlette", "studio", "the studio")
    uvicorn = require("uvicorn", "studio", "the studio")
    require("watchfiles", "studio", "the studio")
    require("tomlkit", "studio", "the studio")
    from shapedisplay.studio.app import build_app
    from shapedisplay.studio.session import Session
    from shapedisplay.studio.wasm import check_model

    check_model(model)

    host = check_host(host, allow_remote)
    session = Session(Path(source), device=device, out_dir=out_dir, options=options or {})
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = bind_port(host, port)
    sock.listen(128)
    sock.set_inheritable(True)
    port = sock.getsockname()[1]
    token = secrets.token_urlsafe(24)
    shown = f"[{host}]" if family == socket.AF_INET6 else host
    hosts = {f"{shown}:{port}", f"localhost:{port}"}
    if addr_is_loopback(host):
        hosts.add(f"127.0.0.1:{port}")
    origins = {f"http://{h}" for h in hosts}
    app = build_app(session, token, hosts, origins, model=model)
    url = f"http://{shown}:{port}/?token={token}"
    if not addr_is_loopback(host):
        print(f"shapedisplay studio: warning: serving on {host}, not only this computer: anyone who can reach "
              f"{host}:{port} and has the token can read the files under {session.root} and edit the scene",
              file=err)
    print(f"shapedisplay studio: {session.source.name} ({session.kind}) at {url}", file=out, flush=True)
    print(f"shapedisplay studio: output folder {session.out_dir}; Ctrl-C stops", file=out, flush=True)
    if open_browser:
        import webbrowser
        webbrowser.open(url)
    config = uvicorn.Config(app, log_level="warning", lifespan="on", ws="websockets-sansio")
    server = uvicorn.Server(config)
    try:
        server.run(sockets=[sock])
    except KeyboardInterrupt:       # Uvicorn has shut down cleanly and re-raises the signal
        pass
    finally:
        sock.close()
    print("shapedisplay studio: stopped", file=out, flush=True)


def bind_port(host: str, port: int | None) -> socket.socket:
    """A socket bound to ``host:port``; ``port=None``: DEFAULT_PORT or the next free one of PORT_TRIES."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    if port is not None and not (isinstance(port, int) and 0 <= port <= 65535):
        raise InputError(f"`--port` must be 0..65535 (got {port!r})")
    # No port asked for: the default, or the next free one after it (another studio may hold it).
    candidates = range(DEFAULT_PORT, DEFAULT_PORT + PORT_TRIES) if port is None else (port,)
    for candidate in candidates:
        sock = socket.socket(family, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((host, candidate))
            break
        except OSError as exc:
            sock.close()
            error = exc
    else:
        if port is None:
            raise InputError(f"no free port on {host} in {candidates[0]}..{candidates[-1]} ({error.strerror or error}); "
                             "choose one with --port N, or --port 0 for any free port") from None
        raise InputError(f"`--port` {port}: cannot listen on {host}:{port} ({error.strerror or error}); "
                         "choose another port or --port 0 for a free one") from None
    return sock


def addr_is_loopback(host: str) -> bool:
    return ipaddress.ip_address(host).is_loopback
