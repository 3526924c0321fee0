"""Screenshots of the viewer's page in headless Chromium, over the Chrome DevTools Protocol (no ROS here).

`chromium --screenshot` shoots when the page's load event fires, before rerun's Wasm viewer has connected
and drawn, so the page is opened in a headless Chromium with a DevTools port and shot when asked
(Page.captureScreenshot), as often as the caller wants. WebGL runs on SwiftShader (CPU): no GPU needed.
cell_view_pixels reads what a shot's 3D view shows; watch_requests follows the page's requests to its data
(a failed connection leaves rerun's page on its welcome screen, which a slow page also shows for a while).
Used by the system test (tests/test_viewer.py) and for the README's screenshot (demo_shot.py); a page shot
by hand:

    python3 -m stylepong_viz.browser_shot URL OUT.png [--wait-s 8]
"""

from __future__ import annotations

import argparse
import base64
import io
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

import numpy as np

DETACHED = 'Not attached to an active page'  # DevTools' answer between two renderers of one tab
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


class RequestWatch:
    """A page's requests to urls that start with `url_prefix`, from DevTools' Network events: when each was
    sent (`sent`: timestamps on time.monotonic()'s clock, which Chromium's are on Linux) and which failed."""

    def __init__(self, url_prefix: str):
        self.url_prefix = url_prefix
        self.sent: list[tuple[float, str]] = []  # (when sent, url)
        self._urls: dict[str, str] = {}  # DevTools request id: url
        self._failed: list[str] = []

    def on_event(self, event: dict) -> None:
        method, params = event.get('method'), event.get('params', {})
        if method == 'Network.requestWillBeSent' and params['request']['url'].startswith(self.url_prefix):
            self._urls[params['requestId']] = params['request']['url']
            self.sent.append((params['timestamp'], params['request']['url']))
        elif method == 'Network.loadingFailed' and params.get('requestId') in self._urls and not params.get('canceled'):
            self._failed.append(f'{self._urls[params["requestId"]]}: {params.get("errorText")}')

    def take_failed(self) -> list[str]:
        """'url: error' for each request that failed since the last call. One the browser cancelled (the page
        navigated away from it) did not fail."""
        failed, self._failed = self._failed, []
        return failed


class HeadlessPage:
    """One headless Chromium showing one page; shoot() returns PNG bytes. Use as a context manager."""

    def __init__(
        self,
        url: str | None = None,
        width: int = 1280,
        height: int = 800,
        start_timeout_s: float = 20.0,
        extra_flags: tuple[str, ...] = (),
    ):
        from websockets.sync.client import connect

        chromium = find_chromium()
        if chromium is None:
            raise BrowserError('no Chromium found (apt install chromium, or set CHROMIUM)')
        self._profile = tempfile.mkdtemp(prefix='stylepong_chromium_')
        port = _free_port()
        # SwiftShader: software WebGL, the same picture on any machine, GPU or not.
        self._process = subprocess.Popen(
            [
                chromium,
                '--headless',
                '--no-sandbox',
                '--use-angle=swiftshader',
                '--enable-unsafe-swiftshader',
                '--no-first-run',
                '--disable-extensions',
                f'--remote-debugging-port={port}',
                f'--window-size={width},{height}',
                f'--user-data-dir={self._profile}',
                *extra_flags,
                'about:blank',
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
        )
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
        self._socket.__enter__()  # websockets wants its sync client entered; close() leaves it
        self._next_id = 0
        self.requests: RequestWatch | None = None  # the page's requests followed (watch_requests)
        self._call('Emulation.setDeviceMetricsOverride', width=width, height=height, deviceScaleFactor=1, mobile=False)
        if url is not None:
            self.navigate(url)

    def navigate(self, url: str) -> None:
        """Open url (a browser started early, before the page is served, saves its start-up time)."""
        self._call('Page.navigate', url=url)

    def watch_requests(self, url_prefix: str) -> None:
        """Follow the page's requests to urls that start with url_prefix: self.requests, and
        take_failed_requests()."""
        self.requests = RequestWatch(url_prefix)
        self._call('Network.enable')

    def take_failed_requests(self) -> list[str]:
        """The followed requests that failed since the last call (RequestWatch.take_failed)."""
        if self.requests is None:
            raise BrowserError('no requests followed: call watch_requests first')
        while True:  # the events that arrived since the last DevTools call
            try:
                message = self._socket.recv(timeout=0)
            except TimeoutError:
                break
            self._on_event(json.loads(message))
        return self.requests.take_failed()

    def _on_event(self, event: dict) -> None:
        if self.requests is not None:
            self.requests.on_event(event)

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
            self._on_event(reply)

    def shoot(self, timeout_s: float = 30.0) -> bytes:
        """The page as it is now, PNG (a software-drawn frame on a busy machine can take tens of seconds)."""
        deadline = time.monotonic() + timeout_s
        while True:
            try:
                reply = self._call(
                    'Page.captureScreenshot', timeout_s=max(1.0, deadline - time.monotonic()), format='png'
                )
                return base64.b64decode(reply['data'])
            except BrowserError as error:
                # While a navigation swaps the page's renderer, the target briefly has no page to shoot.
                if DETACHED not in str(error) or time.monotonic() > deadline:
                    raise
                time.sleep(0.2)

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


def _longest_run(flags: np.ndarray) -> tuple[int, int]:
    """First and last index of the longest run of True (0, -1 when none)."""
    best, start = (0, -1), None
    for k, flag in enumerate(list(flags) + [False]):
        if flag and start is None:
            start = k
        elif not flag and start is not None:
            if k - 1 - start > best[1] - best[0]:
                best = (start, k - 1)
            start = None
    return best


def cell_view_pixels(png: bytes, background_rgb: tuple[int, int, int]) -> dict:
    """What a screenshot's 3D view shows: its region (the bounding box of its dark background) and its table
    (blue), arm (light grey) and ball (orange: ball and trail) pixel counts, and the share of the arm's pixels
    right of the view's vertical centre line."""
    import imageio.v3 as iio

    image = iio.imread(io.BytesIO(png))[:, :, :3].astype(int)
    background = np.all(np.abs(image - np.array(background_rgb)) <= 6, axis=2)
    # The view: the longest run of rows, and then of columns, that are mostly its background colour.
    y0, y1 = _longest_run(background.mean(axis=1) > 0.5)
    if y1 - y0 < 100:
        return {'region': None, 'table': 0, 'arm': 0, 'ball': 0, 'arm_right_fraction': 0.0}
    x0, x1 = _longest_run(background[y0 : y1 + 1].mean(axis=0) > 0.5)
    region = image[y0 : y1 + 1, x0 : x1 + 1]
    r, g, b = region[:, :, 0], region[:, :, 1], region[:, :, 2]
    table = (b > r + 50) & (b > g + 30)
    # The arm's meshes are light grey to white; the table, net (light, but thin and far) and background are not.
    arm = ~background[y0 : y1 + 1, x0 : x1 + 1] & ~table & (np.abs(r - b) < 40) & (r > 90)
    ball = (r > 200) & (g > 90) & (g < 190) & (b < 60)
    centre_x = (x1 - x0) / 2.0
    arm_cols = np.nonzero(arm)[1]
    right = float(np.mean(arm_cols > centre_x + 0.02 * (x1 - x0))) if arm_cols.size else 0.0
    return {
        'region': (int(x0), int(y0), int(x1), int(y1)),
        'table': int(table.sum()),
        'arm': int(arm.sum()),
        'ball': int(ball.sum()),
        'arm_right_fraction': right,
    }


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
