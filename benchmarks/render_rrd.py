"""Render what a person sees on opening an .rrd: rerun's web viewer in headless Chromium, to PNG.

Not a test dependency: it needs two things from the package registries that the project does not
(Python's ``playwright`` driver and Debian's ``chromium``)::

    apt-get install chromium            # Debian's browser; playwright's own browser download is not used
    pip install playwright              # the driver only (no `playwright install`)
    python benchmarks/render_rrd.py out/session.rrd docs/viewer/calib_demo.png
    python benchmarks/render_rrd.py a.rrd a.png b.rrd b.png ...   # several at once

How: ``rerun --serve-web`` (the rerun-sdk's own CLI) hosts the web viewer and the recording on loopback ports and the
.rrd is served over loopback HTTP; Chromium (``--headless --no-sandbox``, software rendering: SwiftShader WebGL) opens
``http://127.0.0.1:PORT/?url=http://127.0.0.1:FILES/NAME.rrd`` at ``--size`` (default 1600×1000), waits ``--wait``
seconds for the data to stream and the layout to settle, and saves a screenshot. The blueprint in the file decides the
layout; nothing is clicked.
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_port(port: int, timeout_s: float) -> None:
    t0 = time.time()
    while time.time() - t0 < timeout_s:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.2)
    raise RuntimeError(f"rerun's web viewer did not listen on 127.0.0.1:{port} within {timeout_s:.0f} s")


def _serve_file_folder(folder: Path, port: int):
    """A loopback HTTP server for ``folder`` that allows cross-origin reads (the viewer is on another port)."""
    import functools
    import threading
    from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer

    class Handler(SimpleHTTPRequestHandler):
        def end_headers(self) -> None:
            self.send_header("Access-Control-Allow-Origin", "*")
            super().end_headers()

        def log_message(self, *args) -> None:
            pass

    httpd = ThreadingHTTPServer(("127.0.0.1", port), functools.partial(Handler, directory=str(folder)))
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    return httpd


CHROMIUM_ARGS = [
    "--headless=new",
    "--no-sandbox",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--ignore-gpu-blocklist",
]


def render(rrd: Path, png: Path, *, size: tuple[int, int] = (1600, 1000), wait_s: float = 25.0,
           chromium: str = "/usr/bin/chromium", renderer: str = "webgl") -> Path:
    """Serve ``rrd`` with rerun's web viewer and screenshot it in headless Chromium; returns ``png``."""
    from playwright.sync_api import sync_playwright

    rerun = shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))
    web, grpc, files = _free_port(), _free_port(), _free_port()
    cmd = [rerun, "--serve-web", "--bind", "127.0.0.1", "--web-viewer-port", str(web), "--port", str(grpc),
           "--renderer", renderer]
    # its own process group: the `rerun` entry point starts the viewer binary as a child, which must end with it
    server = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    # the .rrd itself over HTTP (CORS allowed): the viewer loads the whole file at once, faster than the proxy
    http = _serve_file_folder(rrd.resolve().parent, files)
    try:
        _wait_port(web, 30)
        _wait_port(files, 30)
        url = f"http://127.0.0.1:{web}/?url=http://127.0.0.1:{files}/{rrd.name}&renderer={renderer}"
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=chromium, args=CHROMIUM_ARGS)
            page = browser.new_page(viewport={"width": size[0], "height": size[1]})
            page.goto(url)
            time.sleep(wait_s)
            png.parent.mkdir(parents=True, exist_ok=True)
            page.screenshot(path=str(png), timeout=180_000)  # software WebGL on a loaded machine: minutes
            browser.close()
    finally:
        http.shutdown()
        os.killpg(server.pid, signal.SIGTERM)
        try:
            server.wait(10)
        except subprocess.TimeoutExpired:
            os.killpg(server.pid, signal.SIGKILL)
    return png


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("pairs", nargs="+", help="RRD PNG [RRD PNG ...]")
    ap.add_argument("--size", default="1600x1000", help="browser viewport WIDTHxHEIGHT in CSS pixels")
    ap.add_argument("--wait", type=float, default=25.0, help="seconds to let the data stream and the layout settle")
    ap.add_argument("--chromium", default="/usr/bin/chromium", help="the browser binary (Debian's chromium)")
    ap.add_argument(
        "--renderer", default="webgl", choices=("webgl", "webgpu"), help="the web viewer's graphics backend"
    )
    args = ap.parse_args(argv)
    if len(args.pairs) % 2:
        ap.error("give RRD PNG pairs")
    w, h = (int(v) for v in args.size.lower().split("x"))
    for rrd, png in zip(args.pairs[::2], args.pairs[1::2]):
        if not Path(rrd).is_file():
            ap.error(f"{rrd}: no such file")
        out = render(
            Path(rrd), Path(png), size=(w, h), wait_s=args.wait, chromium=args.chromium, renderer=args.renderer
        )
        print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
