"""The slider page as HTML: served piece by piece on 127.0.0.1, or as one self-contained file.

Both forms run the same scripts on the same data. Served, the page fetches
``scene.json`` and the scripts from the server once and never calls it again (a slider
step is evaluated in the page). Self-contained, the scene is a JSON ``<script>`` element
and every script is inlined, so the file opens from disk with no network at all.
"""

from __future__ import annotations

import html
import threading
from dataclasses import dataclass, field
from functools import cache
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path

from parsel_core.errors import ParselError
from parsel_core.io import atomic_write_text
from parsel_view.scene import PageData

#: Scripts in load order: renderer, evaluator, (the program's amounts), page logic.
STATIC_FILES = ("minigl.js", "parsel_eval.js", "viewer.js", "viewer.css")
HTML_SUFFIXES = (".html", ".htm")


@cache
def static_text(name: str) -> str:
    """A file of the package's ``static/`` folder."""
    return resources.files("parsel_view").joinpath("static", name).read_text(encoding="utf-8")


def _inline_script(text: str) -> str:
    # "</" would end the <script> element early; "<\/" means the same inside JS strings.
    return "<script>\n" + text.replace("</", "<\\/") + "\n</script>"


_BODY = """<div id="panel">
<h1 id="title">{title}</h1>
<div id="request"></div>
<div id="sliders"></div>
<div id="values"></div>
<div id="relations" role="status" aria-live="polite"></div>
<button type="button" id="reset-view">reset view</button>
<details><summary>program</summary><pre id="program"></pre></details>
<div id="status">loading…</div>
</div>
<canvas id="view"></canvas>
<div id="tooltip" hidden></div>"""


def render_html(page: PageData, inline: bool) -> str:
    """The page; ``inline`` puts the scene and every script in the file itself."""
    title = html.escape(str(page.scene["title"]))
    head = ["<!doctype html>", "<html lang=\"en\">", "<head>", "<meta charset=\"utf-8\">",
            "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">",
            f"<title>parsel: {title}</title>"]
    if inline:
        head.append("<style>\n" + static_text("viewer.css") + "</style>")
    else:
        head.append("<link rel=\"stylesheet\" href=\"static/viewer.css\">")
    body = ["</head>", "<body>", _BODY.format(title=title)]
    if inline:
        body.append("<script id=\"parsel-scene\" type=\"application/json\">" + page.scene_json() + "</script>")
        body += [_inline_script(static_text("minigl.js")), _inline_script(static_text("parsel_eval.js")),
                 _inline_script(page.amounts_js), _inline_script(static_text("viewer.js"))]
    else:
        body += ["<script src=\"static/minigl.js\"></script>", "<script src=\"static/parsel_eval.js\"></script>",
                 "<script src=\"program.js\"></script>", "<script src=\"static/viewer.js\"></script>"]
    body += ["</body>", "</html>", ""]
    return "\n".join(head + body)


def check_html_path(path: Path | str) -> Path:
    """A file name the page can be written to (``.html`` / ``.htm`` in an existing folder), else one line."""
    path = Path(path)
    if not path.name.lower().endswith(HTML_SUFFIXES):
        raise ParselError(f"{path}: the page is HTML; give a file name ending in .html or .htm")
    if path.is_dir():
        raise ParselError(f"{path}: is a directory")
    if not path.parent.is_dir():
        raise ParselError(f"{path}: output directory {path.parent} does not exist")
    return path


def write_html(page: PageData, path: Path | str) -> Path:
    """Write the self-contained page to ``path`` atomically (a temporary file renamed over it)."""
    path = check_html_path(path)
    atomic_write_text(path, render_html(page, inline=True))
    return path


def check_port(port: object) -> None:
    """A port parsel may serve on: 0 (any free one) or 1024-65535 (not a privileged port)."""
    if isinstance(port, bool) or not isinstance(port, int) or not (port == 0 or 1024 <= port <= 65535):
        raise ParselError(f"--port {port!r}: choose a port from 1024 to 65535, or 0 for any free one")


@dataclass
class PageServer:
    """The page and its pieces served on 127.0.0.1 from memory by :mod:`http.server`.

    Only loopback is bound: the page is for the person at this machine. ``port=0``
    takes any free port (tests use it)."""

    page: PageData
    port: int = 8765
    quiet: bool = True
    _server: ThreadingHTTPServer | None = field(default=None, init=False, repr=False)
    _thread: threading.Thread | None = field(default=None, init=False, repr=False)

    def routes(self) -> dict[str, tuple[str, bytes]]:
        """URL path -> (content type, body)."""
        index = render_html(self.page, inline=False).encode("utf-8")
        routes = {"/": ("text/html; charset=utf-8", index), "/index.html": ("text/html; charset=utf-8", index),
                  "/scene.json": ("application/json", self.page.scene_json().encode("utf-8")),
                  "/program.js": ("text/javascript; charset=utf-8", self.page.amounts_js.encode("utf-8"))}
        for name in STATIC_FILES:
            kind = "text/css; charset=utf-8" if name.endswith(".css") else "text/javascript; charset=utf-8"
            routes[f"/static/{name}"] = (kind, static_text(name).encode("utf-8"))
        return routes

    @property
    def url(self) -> str:
        if self._server is None:
            raise ParselError("the page server is not running")
        return f"http://127.0.0.1:{self._server.server_address[1]}/"

    def start(self) -> str:
        """Bind and serve in a background thread; returns the page's URL."""
        check_port(self.port)
        routes = self.routes()
        quiet = self.quiet
        hosts: set[str] = set()  # filled once the port is known

        class Handler(BaseHTTPRequestHandler):
            def do_GET(self) -> None:  # noqa: N802 - http.server's name
                if (self.headers.get("Host") or "").lower() not in hosts:
                    # Another site's page reaching 127.0.0.1 under its own name (DNS rebinding).
                    self.send_error(421, "this page answers only to 127.0.0.1 and localhost")
                    return
                path = self.path.split("?", 1)[0]
                if path not in routes:
                    self.send_error(404, "not part of this page")
                    return
                kind, body = routes[path]
                self.send_response(200)
                self.send_header("Content-Type", kind)
                self.send_header("Content-Length", str(len(body)))
                self.send_header("Cache-Control", "no-store")
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, format: str, *args) -> None:  # noqa: A002 - http.server's signature
                if not quiet:
                    super().log_message(format, *args)

        try:
            self._server = ThreadingHTTPServer(("127.0.0.1", self.port), Handler)
        except OSError as exc:
            raise ParselError(f"cannot serve on 127.0.0.1:{self.port}: {exc.strerror} "
                              f"(choose another --port, or 0 for any free one)") from None
        self._server.daemon_threads = True
        port = self._server.server_address[1]
        hosts.update({f"127.0.0.1:{port}", f"localhost:{port}"})
        self._thread = threading.Thread(target=self._server.serve_forever, name="parsel-view", daemon=True)
        self._thread.start()
        return self.url

    def stop(self) -> None:
        if self._server is not None:
            self._server.shutdown()
            self._server.server_close()
            self._server = None

    def __enter__(self) -> PageServer:
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()
