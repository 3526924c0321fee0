#!/usr/bin/env python3
"""viewer: what the browser viewer costs the graph: drag_teach's missed ticks and the player's jitter, without
and with `ros2 run stylepong_viz viewer` running, side by side in one run.

1. drag_teach (defaults: 500 Hz, wall clock) against ur5_sim for DURATION_S; its own count at Ctrl-C
   (cycles, missed ticks: 2 ms periods without a cycle).
2. The player (on ur5_sim's /clock) while rally_eval serves RALLY_BALLS balls; its own /player/status at
   the end (rally_eval's JSON): period jitter p99 while playing (|period - 1/60 s|).
Each without the viewer, with it as it starts (--nice 10) and with it at the graph's priority (--nice 0),
in turn, ROUNDS times: this shared machine's load changes by the minute, so only runs made together
compare. The viewer runs with no browser attached (a browser's WebGL is the browser's cost, on whatever
machine shows the page). CPU shares are of one core over the measured window: the viewer's process, and
the graph's (ur5_sim and the node), which show what the viewer's subscriptions cost their publishers.
Prints one Markdown section for BENCHMARKS.md (`make bench`).
"""

import json
import os
import pathlib
import re
import subprocess
import sys
import tempfile
import time

from stylepong_common import markdown
from stylepong_common.node_process import (
    free_port,
    isolated_ros_env,
    process_cpu_s,
    run_rally_eval,
    start_logged,
    stop_group,
    viewer_command,
)

ROOT = pathlib.Path(__file__).resolve().parent.parent
DURATION_S = 15.0
RALLY_BALLS = 3  # about 15 s of play
ROUNDS = 2
# (label, the viewer's options; None: no viewer)
VARIANTS = (('off', None), ('on', []), ('on, --nice 0', ['--nice', '0']))
DRAG_STATS = re.compile(r'(\d+) cycles in .*? (\d+) missed')


def _wait_for(log: pathlib.Path, text: str, process: subprocess.Popen, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while text not in log.read_text():
        if time.monotonic() > deadline or process.poll() is not None:
            raise RuntimeError(f'{log.name}: no {text!r}:\n' + log.read_text()[-2000:])
        time.sleep(0.2)


def graph_run(what: str, viewer_options: list[str] | None) -> dict:
    """ur5_sim + (drag_teach | player) [+ viewer with viewer_options] for DURATION_S; the measured figures."""
    env = isolated_ros_env()
    logs = pathlib.Path(tempfile.mkdtemp(prefix=f'bench_viewer_{what}_'))
    sim_args = [] if what == 'drag_teach' else ['--ros-args', '-p', 'max_lag_s:=0.01']  # as benchmarks/50_player.py
    sim = start_logged(['ros2', 'run', 'stylepong_sim', 'ur5_sim', *sim_args], env, logs / 'ur5_sim.log')
    processes = [sim]
    viewer = None
    if viewer_options is not None:
        viewer = start_logged(viewer_command(free_port(), *viewer_options), env, logs / 'viewer.log')
        processes.append(viewer)
    status: list[dict] = []
    try:
        if what == 'drag_teach':
            node = start_logged(['ros2', 'run', 'stylepong_fdcc', 'drag_teach'], env, logs / 'node.log')
            processes.append(node)
            _wait_for(logs / 'node.log', 'running', node)
        else:
            # ball_estimator turns the cell's tracker detections into the player's /ball/state.
            processes.append(
                start_logged(['ros2', 'run', 'stylepong_player', 'ball_estimator'], env, logs / 'ball_estimator.log')
            )
            node = start_logged(
                ['ros2', 'run', 'stylepong_player', 'player', '--ros-args', '-p', 'use_sim_time:=true'],
                env,
                logs / 'node.log',
            )
            processes.append(node)
        if viewer is not None:
            _wait_for(logs / 'viewer.log', 'serving', viewer)
        time.sleep(3.0)  # start-up (drag_teach's tare, the player's actor)
        measured = [p for p in (viewer, sim, node) if p is not None]
        cpu_before = [process_cpu_s(p.pid) for p in measured]
        started = time.monotonic()
        if what == 'player':
            status = _rally(env, node, logs)
        else:
            time.sleep(DURATION_S)
        shares = [
            (process_cpu_s(p.pid) - before) / (time.monotonic() - started) for p, before in zip(measured, cpu_before)
        ]
    finally:
        for process in reversed(processes):
            stop_group(process)
    figures = {
        'viewer_cpu': shares[0] if viewer is not None else None,
        'graph_cpu': sum(shares[-2:]),
        'load': os.getloadavg()[0],
    }
    if what == 'drag_teach':
        match = DRAG_STATS.search((logs / 'node.log').read_text())
        if not match:
            raise RuntimeError('drag_teach printed no statistics:\n' + (logs / 'node.log').read_text()[-2000:])
        cycles, missed = (int(x) for x in match.groups())
        return {'cycles': cycles, 'missed': missed, **figures}
    period = status[-1].get('period_ms', {})
    return {'steps': period.get('count'), 'jitter_p99_ms': period.get('jitter_p99'), **figures}


def _rally(env: dict, node: subprocess.Popen, logs: pathlib.Path) -> list[dict]:
    """rally_eval serving RALLY_BALLS balls to the player; the player's status at the end."""
    out = logs / 'rally.json'
    result = run_rally_eval(env, RALLY_BALLS, 900, out)
    if result.returncode != 0 or node.poll() is not None:
        raise RuntimeError('rally_eval failed:\n' + result.stderr[-1000:] + (logs / 'node.log').read_text()[-1000:])
    return [json.loads(out.read_text())['player_status']]


def _cpu_text(share) -> str:
    return '-' if share is None else f'{100.0 * share:.0f} %'


def main() -> int:
    print('## viewer: what the browser viewer costs the graph (drag_teach missed ticks, player jitter)\n')
    print(
        '`python3 benchmarks/70_viewer.py`. ur5_sim with drag_teach (500 Hz, wall clock), and ur5_sim with the '
        f'player (on /clock) while rally_eval serves {RALLY_BALLS} balls of seed 900, drag_teach '
        f'{DURATION_S:.0f} s; without `ros2 run stylepong_viz viewer`, with it as it starts (--nice 10) and with '
        f"it at the graph's priority (--nice 0), no browser attached, in turn, {ROUNDS} rounds. Figures are "
        "the nodes' own: drag_teach's count at Ctrl-C, the player's /player/status (its steps while playing "
        "and their period jitter p99 = |period - 1/60 s|, on the cell's clock, 1 ms resolution). CPU: share "
        "of one core over the measured window, the viewer process's (mean of both runs) and the graph's "
        '(ur5_sim + drag_teach, ur5_sim + player).\n'
    )
    header = ['round', 'viewer', 'drag_teach cycles', 'missed ticks', 'missed %', 'player steps']
    header += ['player jitter p99', 'viewer CPU', 'graph CPU (drag_teach / player)', 'load (1 min)']
    print('\n'.join(markdown.table(header, [])))
    for round_number in range(1, ROUNDS + 1):
        for label, options in VARIANTS:
            drag = graph_run('drag_teach', options)
            player = graph_run('player', options)
            missed_pct = 100.0 * drag['missed'] / max(1, drag['cycles'] + drag['missed'])
            cpu = None if options is None else (drag['viewer_cpu'] + player['viewer_cpu']) / 2.0
            graph_cpu = f'{_cpu_text(drag["graph_cpu"])} / {_cpu_text(player["graph_cpu"])}'
            cells = [round_number, label, drag['cycles'], drag['missed'], f'{missed_pct:.2f} %', player['steps']]
            cells += [f'{player["jitter_p99_ms"]} ms', _cpu_text(cpu), graph_cpu]
            cells += [f'{(drag["load"] + player["load"]) / 2.0:.2f}']
            print(markdown.row([str(cell) for cell in cells]), flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
