"""System tests of `ros2 run stylepong_viz viewer`: the page in headless Chromium, live and from a bag.

The live test starts ur5_sim with the arm held reaching to the robot's right (world -y) and the player
(disabled: it commands nothing), starts the viewer, and shoots its page in headless Chromium until the
cell view shows the table and the arm. The view's camera looks down the table from behind the robot
(stylepong_viz.cell_view), so world -y is right of the view's centre line: an arm drawn from the joint
states lies mostly right of it, while one drawn at the URDF's zero pose or the home pose would not. The
PNG is kept (pytest's tmp dir, its path printed) as the test's artefact.
"""
from __future__ import annotations

import os
import pathlib
import re
import shutil
import signal
import subprocess
import time
import urllib.request

import pytest

from stylepong_common.node_process import NodeProcess, free_port

ROOT = pathlib.Path(__file__).resolve().parent.parent
REACH_RIGHT_RAD = [-1.5, -1.2, 1.2, -1.57, -1.57, -1.57]   # paddle at world y about -0.6 m from the base
# From the viewer's start to a page showing the arm and the table, timed when the screenshot that shows them
# was asked for: under SwiftShader one shot takes 3-5 s to draw, the test's camera and not the viewer.
PAGE_DEADLINE_S = 10.0
RELOAD_AFTER_S = 8.0       # a page without a cell view this long after it was opened is opened again
# Share of the arm's pixels right of the view's centre line: about 0.6 reaching right (the base stands on the
# line), 0.16 at the home pose, less at the URDF's zero pose.
ARM_RIGHT_FRACTION = 0.45
# Chromium draws WebGL on the CPU (SwiftShader): with more runnable work than 2x the cores (a training run
# beside the suite) a frame can take seconds, and the deadline says nothing about the viewer.
OVERLOADED_PER_CORE = 2.0
URL_LINE = re.compile(r'viewer: open (\S+)')
CHROMIUM = shutil.which('chromium') or shutil.which('chromium-browser') or shutil.which('google-chrome')


def _wait_for_url(viewer: NodeProcess, timeout_s: float) -> str:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        match = URL_LINE.search(viewer.output())
        if match:
            return match.group(1)
        assert viewer.running(), viewer.output()
        time.sleep(0.05)
    raise AssertionError('the viewer printed no address:\n' + viewer.output())


@pytest.mark.skipif(CHROMIUM is None, reason='needs Chromium (tools/setup.sh installs it with CI=1)')
def test_page_shows_the_arm_where_the_joint_states_put_it(ros_env, tmp_path):
    from stylepong_viz.browser_shot import BrowserError, HeadlessPage, cell_view_pixels
    from stylepong_viz.cell_view import BACKGROUND_RGB
    sim = NodeProcess('stylepong_sim', 'ur5_sim', params={'home_joint_positions_rad': REACH_RIGHT_RAD}).start()
    player = NodeProcess('stylepong_player', 'player').start()
    web_port, grpc_port = free_port(), free_port()
    viewer = NodeProcess('stylepong_viz', 'viewer', '--web-port', str(web_port), '--grpc-port', str(grpc_port))
    try:
        with HeadlessPage(width=1024, height=640) as browser:    # started first: its start-up is not the viewer's
            time.sleep(2.0)                                        # the sim and the player come up meanwhile
            started = time.monotonic()
            viewer.start()
            url = _wait_for_url(viewer, PAGE_DEADLINE_S)
            browser.navigate(url)
            opened, shots = time.monotonic(), []
            while time.monotonic() - started < PAGE_DEADLINE_S + 15.0:   # keeps looking, to say how late it was
                asked_s = time.monotonic() - started
                try:
                    png = browser.shoot(timeout_s=30.0)
                except BrowserError as error:   # the tab lost its renderer (it crashed): a person reloads it
                    print(f'{time.monotonic() - started:.1f} s: {error}; opening the page again')
                    browser.navigate(url)
                    opened = time.monotonic()
                    continue
                shots.append((asked_s, png, cell_view_pixels(png, BACKGROUND_RGB)))
                found = shots[-1][2]
                if found['table'] > 2000 and found['arm'] > 1000 and found['arm_right_fraction'] > ARM_RIGHT_FRACTION:
                    break
                if found['region'] is None and time.monotonic() - opened > RELOAD_AFTER_S:
                    # Still no cell view: rerun's page stays on its welcome screen when its first connection to
                    # the data fails (seen on a saturated machine); a person reloads, and so does the test.
                    browser.navigate(url)
                    opened = time.monotonic()
                time.sleep(0.5)
        print('shots (s after start, when asked for: table, arm pixels, right share):',
              ', '.join(f'{t:.1f}: {f["table"]}/{f["arm"]}/{f["arm_right_fraction"]:.2f}' for t, _, f in shots))
        assert shots, f'Chromium gave no screenshot in {PAGE_DEADLINE_S + 15.0:.0f} s'
        elapsed_s, png, found = shots[-1]
        artefact = tmp_path / 'viewer_live.png'
        artefact.write_bytes(png)
        print(f'viewer page after {elapsed_s:.1f} s: {found}; screenshot {artefact}')
        assert found['region'] is not None, f'no cell view on the page: {artefact}'
        assert found['table'] > 2000, f'no table drawn: {found}, {artefact}'
        assert found['arm'] > 1000, f'no arm drawn: {found}, {artefact}'
        assert found['arm_right_fraction'] > ARM_RIGHT_FRACTION, \
            f'the arm is not where the joint states put it: {found}, {artefact}'
        load = os.getloadavg()[0]
        if load <= OVERLOADED_PER_CORE * os.cpu_count():
            assert elapsed_s <= PAGE_DEADLINE_S, \
                f'the page showed the cell only in a shot asked for {elapsed_s:.1f} s after start'
        else:   # the content is still checked above; only its timing is not judged on a saturated machine
            print(f'load average {load:.1f} on {os.cpu_count()} cores: the {PAGE_DEADLINE_S:.0f} s deadline '
                  f'is not judged ({elapsed_s:.1f} s)')
        assert viewer.running() and sim.running() and player.running(), viewer.output()
    finally:
        for node in (viewer, player, sim):
            node.stop(timeout_s=10.0)


def _bag_clip() -> pathlib.Path:
    return sorted((ROOT / 'ros2_ws' / 'bags').glob('forward_*'))[0]


def _viewer_command(*args: str) -> list[str]:
    return ['ros2', 'run', 'stylepong_viz', 'viewer', *args]


def test_bag_is_served_with_its_joint_states(tmp_path):
    from rosbags.highlevel import AnyReader
    clip = _bag_clip()
    with AnyReader([clip]) as reader:
        joint_states = sum(c.msgcount for c in reader.connections if c.topic == '/joint_states')
    web_port = free_port()
    log = tmp_path / 'viewer_bag.log'
    with open(log, 'w') as out:
        process = subprocess.Popen(_viewer_command('--bag', str(clip), '--web-port', str(web_port), '--grpc-port',
                                                   str(free_port())), stdout=out, stderr=subprocess.STDOUT,
                                   env=dict(os.environ, PYTHONUNBUFFERED='1'), start_new_session=True)
        try:
            deadline = time.monotonic() + 30.0
            while f'/joint_states {joint_states}' not in log.read_text():
                assert process.poll() is None and time.monotonic() < deadline, log.read_text()
                time.sleep(0.1)
            with urllib.request.urlopen(f'http://127.0.0.1:{web_port}/', timeout=5.0) as page:
                assert page.status == 200 and b'rerun' in page.read().lower()
        finally:
            os.killpg(process.pid, signal.SIGINT)
            assert process.wait(10) == 0, log.read_text()


def _damaged_copy(tmp_path: pathlib.Path) -> pathlib.Path:
    clip = _bag_clip()
    damaged = tmp_path / clip.name
    shutil.copytree(clip, damaged)
    mcap = next(damaged.glob('*.mcap'))
    data = mcap.read_bytes()
    mcap.write_bytes(data[:len(data) // 3])     # a recording cut short: no footer, half a chunk
    return damaged


@pytest.mark.parametrize('case', ['missing', 'damaged', 'not_a_bag'])
def test_bad_bag_gives_one_line_and_exit_code_2(tmp_path, case):
    if case == 'missing':
        path = tmp_path / 'no_such_clip'
    elif case == 'damaged':
        path = _damaged_copy(tmp_path)
    else:
        path = tmp_path / 'notes'
        path.mkdir()
        (path / 'readme.txt').write_text('not a bag')
    result = subprocess.run(_viewer_command('--bag', str(path), '--web-port', str(free_port()), '--grpc-port',
                                            str(free_port())), capture_output=True, text=True, timeout=60)
    print(result.stderr)
    assert result.returncode == 2, result.stdout + result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and result.stderr.startswith('viewer: '), result.stderr
    assert str(path.name) in result.stderr
