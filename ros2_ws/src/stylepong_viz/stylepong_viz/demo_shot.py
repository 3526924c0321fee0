"""The README's picture of the viewer: ur5_sim and the player up, rally_eval serving balls, the page shot in
headless Chromium while a ball is in flight.

    python3 -m stylepong_viz.demo_shot docs/viewer.png [--balls 3] [--first-seed 900]

It shoots the page every SHOT_PERIOD_S while the rally runs and keeps the shot whose 3D view shows the most
of the ball and its trail, with the arm and the table in view (browser_shot.cell_view_pixels). Exit code 2
when no Chromium is found, 1 when no shot showed a ball.
"""

from __future__ import annotations

import argparse
import pathlib
import re
import subprocess
import sys
import tempfile
import time

from stylepong_common.node_process import free_port, isolated_ros_env, start_logged, stop_group, viewer_command
from stylepong_viz.browser_shot import BrowserError, HeadlessPage, cell_view_pixels
from stylepong_viz.cell_view import BACKGROUND_RGB

SHOT_PERIOD_S = 0.3
SHOT_TIMEOUT_S = 120.0
URL_LINE = re.compile(r'viewer: open (\S+)')
START_TIMEOUT_S = 60.0
# A shot counts when its 3D view holds the table and the arm, and at least this many ball/trail pixels.
MIN_BALL_PIXELS = 20


def _wait_for_url(log: pathlib.Path, viewer: subprocess.Popen) -> str:
    deadline = time.monotonic() + START_TIMEOUT_S
    while time.monotonic() < deadline and viewer.poll() is None:
        match = URL_LINE.search(log.read_text(errors='replace'))
        if match:
            return match.group(1)
        time.sleep(0.1)
    raise RuntimeError('the viewer printed no address:\n' + log.read_text(errors='replace')[-2000:])


def _wait_for_cell(browser: HeadlessPage, url: str) -> None:
    """Shoot the page until it shows the table and the arm (at most START_TIMEOUT_S). Under SwiftShader on a
    small machine that takes tens of seconds, on rerun's welcome screen; a page whose data connection failed
    stays there for good (rerun does not connect again), and only that one is opened again."""
    deadline = time.monotonic() + START_TIMEOUT_S
    while time.monotonic() < deadline:
        found = cell_view_pixels(browser.shoot(timeout_s=SHOT_TIMEOUT_S), BACKGROUND_RGB)
        if found['table'] > 2000 and found['arm'] > 1000:
            return
        failed = browser.take_failed_requests()
        if failed:
            print(f'demo_shot: the page could not read its data ({failed}); opening it again')
            browser.navigate(url)
        time.sleep(SHOT_PERIOD_S)
    print(f'demo_shot: no cell view on the page in {START_TIMEOUT_S:.0f} s; the rally starts anyway')


def shoot_rally(out: pathlib.Path, balls: int, first_seed: int, width: int, height: int) -> dict | None:
    """Run the cell, the player, the viewer and a rally; write the best shot to `out`; its pixel counts."""
    env = isolated_ros_env()
    logs = pathlib.Path(tempfile.mkdtemp(prefix='viewer_demo_shot_'))
    processes = [
        start_logged(['ros2', 'run', 'stylepong_sim', 'ur5_sim'], env, logs / 'ur5_sim.log'),
        start_logged(
            ['ros2', 'run', 'stylepong_player', 'player', '--ros-args', '-p', 'use_sim_time:=true'],
            env,
            logs / 'player.log',
        ),
    ]
    best: tuple[int, bytes, dict] | None = None
    try:
        with HeadlessPage(width=width, height=height, start_timeout_s=START_TIMEOUT_S) as browser:
            grpc_port = free_port()
            viewer = start_logged(viewer_command(grpc_port), env, logs / 'viewer.log')
            processes.append(viewer)
            browser.watch_requests(f'http://127.0.0.1:{grpc_port}/')
            url = _wait_for_url(logs / 'viewer.log', viewer)
            browser.navigate(url)
            time.sleep(5.0)  # the player's actor
            _wait_for_cell(browser, url)
            rally = start_logged(
                ['ros2', 'run', 'stylepong_sim', 'rally_eval', '--balls', str(balls), '--first-seed', str(first_seed)],
                env,
                logs / 'rally.log',
            )
            processes.append(rally)
            while rally.poll() is None:
                png = browser.shoot(timeout_s=SHOT_TIMEOUT_S)
                found = cell_view_pixels(png, BACKGROUND_RGB)
                if found['table'] > 2000 and found['arm'] > 1000 and (best is None or found['ball'] > best[0]):
                    best = (found['ball'], png, found)
                time.sleep(SHOT_PERIOD_S)
    finally:
        for process in reversed(processes):
            stop_group(process)
    print(f'demo_shot: logs in {logs}; the best shot: {best[2] if best else None}')
    if best is None or best[0] < MIN_BALL_PIXELS:
        return None
    out.write_bytes(best[1])
    return best[2]


def main(argv: list[str] | None = None) -> int:
    """Shoot the rally into OUT."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('out', type=pathlib.Path)
    parser.add_argument('--balls', type=int, default=3)
    parser.add_argument('--first-seed', type=int, default=900)
    parser.add_argument('--width', type=int, default=1280)
    parser.add_argument('--height', type=int, default=800)
    args = parser.parse_args(argv)
    try:
        found = shoot_rally(args.out, args.balls, args.first_seed, args.width, args.height)
    except BrowserError as error:
        print(f'demo_shot: {error}', file=sys.stderr)
        return 2
    if found is None:
        print('demo_shot: no shot showed a ball in flight with the arm and the table', file=sys.stderr)
        return 1
    print(f'demo_shot: wrote {args.out}: {found}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
