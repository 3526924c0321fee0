"""System tests of `ros2 run stylepong_viz viewer`: the page in headless Chromium, live and from a bag.

The live test starts ur5_sim with the arm held reaching to the robot's right (world -y) and the player
(disabled: it commands nothing), then the viewer, and checks two things:
- the viewer is ready in time: from its start to its log line saying the arm went to the page's server at
  its /joint_states pose (the table and the robot's meshes are logged before the page's address is printed)
  within VIEWER_DEADLINE_S, unless the machine is overloaded;
- the page shows it: shot in headless Chromium until the cell view shows the table and the arm, within
  PAGE_TIMEOUT_S of opening the page. The view's camera looks down the table from behind the robot
  (stylepong_viz.cell_view), so world -y is right of the view's centre line: an arm drawn from the joint
  states lies mostly right of it, while one drawn at the URDF's zero pose or the home pose would not.
How long the page took is printed, not judged: it is the browser's (see PAGE_TIMEOUT_S). The last shot is
kept (pytest's tmp dir, its path printed) as the test's artefact.
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
REACH_RIGHT_RAD = [-1.5, -1.2, 1.2, -1.57, -1.57, -1.57]  # paddle at world y about -0.6 m from the base
# The viewer's own readiness: from its start to the arm served at the joint states' pose. This is the test's
# deadline: what follows is the browser's work.
VIEWER_DEADLINE_S = 10.0
VIEWER_TIMEOUT_S = 60.0  # waited for that line at most, to say how late it was
# The page, timed from opening it, is given a generous timeout and not a deadline. Under SwiftShader (WebGL on
# the CPU) on 2 busy cores, rerun's page takes 5-15 s to compile its 43 MB of Wasm and ask for its data, then
# 1-5 s a frame, and 5-17 s for the first frames that draw the 3D view (a shot waits for a frame); the shot
# that showed the posed arm was asked for 23-34 s after opening. The old deadline (10 s from the viewer's
# start) timed the machine's CPU, not the viewer: a viewer sending 20x fewer triangles, only the 3D view or
# a 2 Hz stream was not measurably quicker on the page.
PAGE_TIMEOUT_S = 60.0
# Share of the arm's pixels right of the view's centre line: about 0.6 reaching right (the base stands on the
# line), 0.16 at the home pose, less at the URDF's zero pose (what the page draws before the arm's transforms
# are in: a shot can show the table and that arm first).
ARM_RIGHT_FRACTION = 0.45
# With more runnable work than 2x the cores (a training run beside the suite), the viewer, niced by design
# once serving, waits for the graph and the browser: its deadline says nothing then.
OVERLOADED_PER_CORE = 2.0
MAX_REOPENS = 2  # a page that lost its renderer or its data connection is opened again, this often
URL_LINE = re.compile(r'viewer: open (\S+)')
SIM_READY_LINE = re.compile(r'UR5 cell ready')
PLAYER_READY_LINE = re.compile(r'\]: player: .* actor ')
GRAPH_TIMEOUT_S = 60.0
CHROMIUM = shutil.which('chromium') or shutil.which('chromium-browser') or shutil.which('google-chrome')


def _wait_for_line(node: NodeProcess, line: re.Pattern, timeout_s: float) -> re.Match:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        match = line.search(node.output())
        if match:
            return match
        assert node.running(), node.output()
        time.sleep(0.05)
    raise AssertionError(f'{node.command[3]} logged no {line.pattern!r} in {timeout_s:.0f} s:\n' + node.output())


def _shows_the_arm_posed(found: dict) -> bool:
    return found['table'] > 2000 and found['arm'] > 1000 and found['arm_right_fraction'] > ARM_RIGHT_FRACTION


@pytest.mark.slow  # the page takes 20-35 s to draw under SwiftShader: .ci/run runs it, `make test` skips it
@pytest.mark.skipif(CHROMIUM is None, reason='needs Chromium (tools/setup.sh installs it with CI=1)')
def test_page_shows_the_arm_where_the_joint_states_put_it(ros_env, tmp_path):
    from stylepong_viz.browser_shot import BrowserError, HeadlessPage, cell_view_pixels
    from stylepong_viz.cell_view import BACKGROUND_RGB
    from stylepong_viz.viewer_node import ARM_SENT_MESSAGE

    sim = NodeProcess('stylepong_sim', 'ur5_sim', params={'home_joint_positions_rad': REACH_RIGHT_RAD}).start()
    player = NodeProcess('stylepong_player', 'player').start()
    web_port, grpc_port = free_port(), free_port()
    viewer = NodeProcess('stylepong_viz', 'viewer', '--web-port', str(web_port), '--grpc-port', str(grpc_port))
    try:
        with HeadlessPage(width=1024, height=640) as browser:  # started first: its start-up is not the viewer's
            # The page's data requests, to tell a failed connection from a slow page: both show rerun's welcome
            # screen (a healthy page shows it until its first data frame is drawn), but only the failed one
            # stays there, as rerun does not connect again.
            browser.watch_requests(f'http://127.0.0.1:{grpc_port}/')
            # The graph up first: started beside the sim and the player (Python, MuJoCo, torch) on 2 cores, the
            # viewer's time to ready would also time their start-up, and it needs the sim's joint states.
            for node, line in ((sim, SIM_READY_LINE), (player, PLAYER_READY_LINE)):
                _wait_for_line(node, line, GRAPH_TIMEOUT_S)
            started = time.monotonic()
            viewer.start()
            url = _wait_for_line(viewer, URL_LINE, VIEWER_TIMEOUT_S).group(1)
            _wait_for_line(viewer, re.compile(re.escape(ARM_SENT_MESSAGE)), VIEWER_TIMEOUT_S)
            ready_s = time.monotonic() - started
            # Opened once the viewer is ready, not at its address: the page's Wasm compiling on both cores
            # would otherwise be timed as the viewer's (niced once serving) and the page loses 1-5 s only.
            browser.navigate(url)
            opened, shots, reopened = time.monotonic(), [], []
            page_deadline = opened + PAGE_TIMEOUT_S
            while time.monotonic() < page_deadline:
                asked_s = time.monotonic() - opened
                try:
                    png = browser.shoot(timeout_s=PAGE_TIMEOUT_S)
                except BrowserError as error:  # the tab lost its renderer (it crashed)
                    failure = str(error)
                else:
                    shots.append((asked_s, png, cell_view_pixels(png, BACKGROUND_RGB)))
                    if _shows_the_arm_posed(shots[-1][2]):
                        break
                    # A failed data connection leaves rerun's page on its welcome screen for good. Only then is
                    # it opened again: a page that is merely slow is left to finish (opening it again restarts
                    # its 5-15 s of start-up, which kept a CI run from ever showing the cell).
                    failure = '; '.join(browser.take_failed_requests())
                if failure:  # what a person would do: reload the page
                    reopened.append(f'{time.monotonic() - opened:.1f} s: {failure}')
                    assert len(reopened) <= MAX_REOPENS, f'the page failed {len(reopened)} times: {reopened}'
                    browser.navigate(url)
                    page_deadline = time.monotonic() + PAGE_TIMEOUT_S  # a page opened again starts over
                time.sleep(0.5)
            connected = [sent - opened for sent, _ in browser.requests.sent if sent >= opened]
        print(f'viewer ready (the arm served at its /joint_states pose) {ready_s:.1f} s after its start')
        print(
            f'page asked for its data {connected[0]:.1f} s after it was opened'
            if connected
            else 'the page never asked for its data'
        )
        print(
            'shots (s after the page was opened, when asked for: table, arm pixels, right share):',
            ', '.join(f'{t:.1f}: {f["table"]}/{f["arm"]}/{f["arm_right_fraction"]:.2f}' for t, _, f in shots),
        )
        if reopened:
            print(f'page opened again: {reopened}')
        assert shots, f'Chromium gave no screenshot in {PAGE_TIMEOUT_S:.0f} s'
        elapsed_s, png, found = shots[-1]
        artefact = tmp_path / 'viewer_live.png'
        artefact.write_bytes(png)
        print(f'viewer page {elapsed_s:.1f} s after it was opened: {found}; screenshot {artefact}')
        assert found['region'] is not None, f'no cell view on the page in {PAGE_TIMEOUT_S:.0f} s: {artefact}'
        assert found['table'] > 2000, f'no table drawn: {found}, {artefact}'
        assert found['arm'] > 1000, f'no arm drawn: {found}, {artefact}'
        assert found['arm_right_fraction'] > ARM_RIGHT_FRACTION, (
            f'the arm is not where the joint states put it: {found}, {artefact}'
        )
        load = os.getloadavg()[0]
        if load <= OVERLOADED_PER_CORE * os.cpu_count():
            assert ready_s <= VIEWER_DEADLINE_S, f'the viewer served the posed arm only {ready_s:.1f} s after start'
        else:  # the page is still checked above; only the viewer's timing is not judged on a saturated machine
            print(
                f'load average {load:.1f} on {os.cpu_count()} cores: the {VIEWER_DEADLINE_S:.0f} s deadline '
                f'is not judged ({ready_s:.1f} s)'
            )
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
        process = subprocess.Popen(
            _viewer_command('--bag', str(clip), '--web-port', str(web_port), '--grpc-port', str(free_port())),
            stdout=out,
            stderr=subprocess.STDOUT,
            env=dict(os.environ, PYTHONUNBUFFERED='1'),
            start_new_session=True,
        )
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
    mcap.write_bytes(data[: len(data) // 3])  # a recording cut short: no footer, half a chunk
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
    result = subprocess.run(
        _viewer_command('--bag', str(path), '--web-port', str(free_port()), '--grpc-port', str(free_port())),
        capture_output=True,
        text=True,
        timeout=60,
    )
    print(result.stderr)
    assert result.returncode == 2, result.stdout + result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and result.stderr.startswith('viewer: '), result.stderr
    assert str(path.name) in result.stderr
