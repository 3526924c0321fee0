#!/usr/bin/env bash
# The sim2sim test through ROS: ur5_sim with realistic sensing + ball_estimator + player + rally_eval, and its result.
#
#   tools/sim2sim.sh [--actor PATH.pt] [--seeds N] [--first-seed S] [--balls N] [--json OUT.json]
#                    [--engine mujoco|pybullet] [--actuator ideal|ur_servoj] [--servo-rate-hz 125]
#                    [--lookahead-s 0.03] [--gain 2000] [--ball-source estimator|cell] [--real-time-factor 0.5]
#
# --ball-source estimator (the default): the cell's tracker publishes positions only
# (config/tracker_sensing.yaml: 150 Hz, 20 ms, 3 mm, lost and false detections) and ball_estimator gives the
# player /ball/state; cell: the path before the estimator, the cell's /ball/state with noisy velocities
# (config/realistic_sensing.yaml), kept for comparison.
# --engine pybullet runs the PyBullet cell (Bullet's own contacts: the paper's Table IV setting); --actuator
# ur_servoj puts the UR controller's servoj between the player's commands and the joints (ur_servoj.py).
# ur5_sim is paced by the wall clock at --real-time-factor (0.5: simulated time runs at half the wall clock's
# pace). Every node of the loop lives on simulated time (the cell's /clock, the detections' stamps), so the pace
# changes no figure of the arm or the ball; it gives the four nodes the CPU they need. On a 2-core machine at
# 1.0 the cell falls behind its schedule and the player misses states (the style actor behind ur_servoj in the
# PyBullet cell, validation seeds 900-901 x 20: 0.95 at 0.5, 0.80 at 1.0); on a robot the player has its own
# computer. The player runs the actor's ONNX export on the cell's /clock; rally_eval serves
# the balls of `evaluate`'s seeds through /sim/launch_ball and scores each rally. The JSON has
# `evaluate`'s fields plus `world` (the setting) and the player's timing; Table IV of `paper_tables`
# reads results/sim2sim_*.json. Needs `source ros2_ws/install/setup.bash`.
# --seeds, --first-seed and --balls default to rally_eval's, which are the evaluation protocol's
# (stylepong_sim.world_spec: EVALUATION_SEEDS from FIRST_EVALUATION_SEED, ROS_EVALUATION_BALLS_PER_SEED each).
set -eo pipefail
cd "$(dirname "$0")/.."
ACTOR=ros2_ws/src/stylepong_policy/models/amp_actor.pt
RALLY_ARGS=()   # only what was given: the rest is rally_eval's defaults
JSON=results/sim2sim_ros.json
ENGINE=mujoco
ACTUATOR=ideal
SERVO_RATE_HZ=125.0
LOOKAHEAD_S=0.03
GAIN=2000.0
BALL_SOURCE=estimator
REAL_TIME_FACTOR=0.5
COMMAND="tools/sim2sim.sh $*"
while [ $# -gt 0 ]; do
  case "$1" in
    --actor) ACTOR=$2; shift 2 ;;
    --seeds|--first-seed|--balls) RALLY_ARGS+=("$1" "$2"); shift 2 ;;
    --json) JSON=$2; shift 2 ;;
    --engine) ENGINE=$2; shift 2 ;;
    --actuator) ACTUATOR=$2; shift 2 ;;
    --servo-rate-hz) SERVO_RATE_HZ=$2; shift 2 ;;
    --lookahead-s) LOOKAHEAD_S=$2; shift 2 ;;
    --gain) GAIN=$2; shift 2 ;;
    --ball-source) BALL_SOURCE=$2; shift 2 ;;
    --real-time-factor) REAL_TIME_FACTOR=$2; shift 2 ;;
    *) echo "sim2sim: unknown argument $1" >&2; exit 2 ;;
  esac
done
case "$ENGINE" in mujoco|pybullet) ;; *) echo "sim2sim: --engine must be mujoco or pybullet, got '$ENGINE'" >&2; exit 2 ;; esac
case "$ACTUATOR" in ideal|ur_servoj) ;; *) echo "sim2sim: --actuator must be ideal or ur_servoj, got '$ACTUATOR'" >&2; exit 2 ;; esac
case "$BALL_SOURCE" in
  estimator) SENSING_FILE=tracker_sensing.yaml ;;
  cell) SENSING_FILE=realistic_sensing.yaml ;;
  *) echo "sim2sim: --ball-source must be estimator or cell, got '$BALL_SOURCE'" >&2; exit 2 ;;
esac
[ -f "${ACTOR%.pt}.onnx" ] || { echo "sim2sim: ${ACTOR%.pt}.onnx is missing (python3 -m stylepong_policy.rl.export --onnx $ACTOR)" >&2; exit 2; }
SENSING="$(ros2 pkg prefix stylepong_sim)/share/stylepong_sim/config/$SENSING_FILE"
LOGS=$(mktemp -d /tmp/sim2sim.XXXXXX)
export ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-$((RANDOM % 100 + 1))}
source tools/node_group.sh
echo "[sim2sim] $ACTOR through ROS: ur5_sim (engine $ENGINE, actuator $ACTUATOR, $SENSING_FILE) + ball source $BALL_SOURCE + player + rally_eval ${RALLY_ARGS[*]:-(the evaluation seeds and balls)}; logs in $LOGS"
start_node "$LOGS/ur5_sim.log" ros2 run stylepong_sim ur5_sim --ros-args --params-file "$SENSING" -p engine:="$ENGINE" \
  -p actuator:="$ACTUATOR" -p servo_rate_hz:="$SERVO_RATE_HZ" -p lookahead_s:="$LOOKAHEAD_S" -p gain:="$GAIN" \
  -p real_time_factor:="$REAL_TIME_FACTOR"
sleep 3
# The cell refuses a bad setting at start (one line, exit code 2): pass it on rather than wait for it.
kill -0 "${NODE_PIDS[0]}" 2>/dev/null || { grep -v '^\[' "$LOGS/ur5_sim.log" >&2; exit 2; }
# The estimator runs on the detections' stamps: no use_sim_time, so it does not take the cell's 1 kHz /clock
# (which cost it two thirds of its CPU on this 2-core machine, where the graph is at its limit).
[ "$BALL_SOURCE" = cell ] || start_node "$LOGS/ball_estimator.log" ros2 run stylepong_player ball_estimator
start_node "$LOGS/player.log" ros2 run stylepong_policy player --ros-args -p actor:="$PWD/$ACTOR" -p use_sim_time:=true
mkdir -p "$(dirname "$JSON")"
ros2 run stylepong_sim rally_eval "${RALLY_ARGS[@]}" --speed all \
  --json "$JSON.part" 2>"$LOGS/rally_eval.err" | tee "$LOGS/rally_eval.log" | grep '^seed' | sed 's/^/[sim2sim]   /'
stop_nodes
python3 - "$JSON.part" "$JSON" "$ACTOR" "$ENGINE" "$ACTUATOR" "$SERVO_RATE_HZ" "$LOOKAHEAD_S" "$GAIN" "$COMMAND" "$BALL_SOURCE" \
  "$REAL_TIME_FACTOR" <<'PY'
import json
import pathlib
import sys

part, out, actor = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2]), sys.argv[3]
engine, actuator, rate_hz, lookahead_s, gain, command, ball_source, real_time_factor = sys.argv[4:12]
result = json.loads(part.read_text())
cell = 'ur5_sim (MuJoCo cell)' if engine == 'mujoco' else 'ur5_sim engine pybullet (PyBullet cell, Bullet contacts)'
drive = ('ideal actuator' if actuator == 'ideal' else
         f'ur_servoj actuator at {float(rate_hz):g} Hz, look-ahead {float(lookahead_s):g} s, gain {float(gain):g}')
seeds = result['seeds']
sensing = ('a 150 Hz tracker reporting positions (config/tracker_sensing.yaml) and ball_estimator'
           if ball_source == 'estimator' else
           "the cell's /ball/state with noisy velocities (config/realistic_sensing.yaml)")
result['world'] = (f'{cell} through ROS, {drive}: player (ONNX, commands streamed, ball carried forward) + '
                   f'rally_eval, {sensing}, paced at {float(real_time_factor):g} x the wall clock, '
                   f'seeds {seeds[0]}-{seeds[-1]}')
result['ball_source'] = ball_source
result['engine'] = engine
result['actuator'] = {'model': actuator, 'servo_rate_hz': float(rate_hz), 'lookahead_s': float(lookahead_s),
                      'gain': float(gain)}
result['real_time_factor'] = float(real_time_factor)
result['command'] = command
result['actor'] = actor
out.write_text(json.dumps(result, indent=2) + '\n')
part.unlink()
print(f"[sim2sim] success rate {result['success_rate']:.3f} over {result['balls']} balls, hit rate "
      f"{result['hit_rate']:.3f}, failures {result['failures']}; written to {out}")
PY
