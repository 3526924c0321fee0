"""Screenshots of the viewer's page in headless Chromium, over the Chrome DevTools Protocol (no ROS here).

`chromium --screenshot` shoots when the page's load event fires, before rerun's Wasm viewer has connected
and drawn, so the page is opened in a headless Chromium with a DevTools port and shot when asked
(Page.captureScreenshot), as often as the caller wants. WebGL runs on SwiftShader (CPU): no GPU needed.
Used by the system test (tests/test_viewer.py) and for the README's screenshot:

    python3 -m stylepong_viz.browser_shot URL OUT.png [--wait-s 8]
"""
from __future__ import annotations

import argparse
import base64
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request

CHROMIUM_NAMES = ('chromium', 'chromium-browser', 'google-chrome', 'google-chrome-stable')


class BrowserError(RuntimeError):
    """No Chromium, or it did not answer."""


def find_chromium() -> str | None:
    """The first Chromium on PATH (or $CHROMIUM)."""
    if os.environ.get('CHROMIUM'):
        return os.environ['CHROMIUM']
    for name in CHROMIUM_NAMES:
        path = shutil.which(name)
        if path:
            return path
    return None


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(('127.0.0.1', 0))
        return probe.getsockname()[1]


class HeadlessPage:
    """One headless Chromium showing one page; shoot() returns PNG bytes. Use as a context manager."""

    def __init__(self, url: str | None = None, width: int = 1280, height: int = 800, start_timeout_s: float = 20.0):
        from websockets.sync.client import connect
        chromium = find_chromium()
        if chromium is None:
            raise BrowserError('no Chromium found (apt install chromium, or set CHROMIUM)')
        self._profile = tempfile.mkdtemp(prefix='stylepong_chromium_')
        port = _free_port()
        # SwiftShader: software WebGL, the same picture on any machine, GPU or not.
        self._process = subprocess.Popen(
            [chromium, '--headless', '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
             '--no-first-run', '--disable-extensions', f'--remote-debugging-port={port}',
             f'--window-size={width},{height}', f'--user-data-dir={self._profile}', 'about:blank'],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        deadline = time.monotonic() + start_timeout_s
        targets = None
        while targets is None:
            try:
                with urllib.request.urlopen(f'http://127.0.0.1:{port}/json', timeout=1.0) as answer:
                    targets = [t for t in json.load(answer) if t.get('type') == 'page']
            except OSError:
                if time.monotonic() > deadline or self._process.poll() is not None:
                    self.close()
                    raise BrowserError(f'{chromium} did not open its DevTools port in {start_timeout_s:.0f} s')
                time.sleep(0.1)
        self._socket = connect(targets[0]['webSocketDebuggerUrl'], max_size=64 * 1024 * 1024, open_timeout=10)
        self._socket.__enter__()   # websockets wants its sync client entered; close() leaves it
        self._next_id = 0
        self._call('Emulation.setDeviceMetricsOverride', width=width, height=height, deviceScaleFactor=1, mobile=False)
        if url is not None:
            self.navigate(url)

    def navigate(self, url: str) -> None:
        """Open url (a browser started early, before the page is served, saves its start-up time)."""
        self._call('Page.navigate', url=url)

    def _call(self, method: str, timeout_s: float = 30.0, **params) -> dict:
        self._next_id += 1
        self._socket.send(json.dumps({'id': self._next_id, 'method': method, 'params': params}))
        deadline = time.monotonic() + timeout_s
        while True:
            reply = json.loads(self._socket.recv(timeout=max(0.1, deadline - time.monotonic())))
            if reply.get('id') == self._next_id:
                if 'error' in reply:
                    raise BrowserError(f'{method}: {reply["error"]}')
                return reply.get('result', {})

    def shoot(self) -> bytes:
        """The page as it is now, PNG."""
        return base64.b64decode(self._call('Page.captureScreenshot', format='png')['data'])

    def close(self) -> None:
        sock = getattr(self, '_socket', None)
        if sock is not None:
            sock.close()
        if self._process.poll() is None:
            os.killpg(self._process.pid, signal.SIGTERM)
            try:
                self._process.wait(5)
            except subprocess.TimeoutExpired:
                os.killpg(self._process.pid, signal.SIGKILL)
                self._process.wait()
        shutil.rmtree(self._profile, ignore_errors=True)

    def __enter__(self) -> HeadlessPage:
        return self

    def __exit__(self, *_exc) -> None:
        self.close()


def main(argv: list[str] | None = None) -> int:
    """Shoot URL into OUT after --wait-s seconds."""
    parser = argparse.ArgumentParser(description='Screenshot of a page in headless Chromium')
    parser.add_argument('url')
    parser.add_argument('out')
    parser.add_argument('--wait-s', type=float, default=8.0)
    parser.add_argument('--width', type=int, default=1280)
    parser.add_argument('--height', type=int, default=800)
    args = parser.parse_args(argv)
    try:
        with HeadlessPage(args.url, args.width, args.height) as page:
            time.sleep(args.wait_s)
            png = page.shoot()
    except BrowserError as error:
        print(f'browser_shot: {error}', file=sys.stderr)
        return 2
    with open(args.out, 'wb') as out:
        out.write(png)
    print(f'browser_shot: wrote {args.out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
