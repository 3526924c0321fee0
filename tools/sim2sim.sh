#!/usr/bin/env bash
# The sim2sim test through ROS: ur5_sim with realistic sensing + player + rally_eval, and its result.
#
#   tools/sim2sim.sh [--actor PATH.pt] [--seeds 10] [--first-seed 1000] [--balls 20] [--json OUT.json]
#
# ur5_sim runs with config/realistic_sensing.yaml (camera noise, 25 ms latency, lost frames, F/T noise),
# paced by the wall clock; the player runs the actor's ONNX export on the cell's /clock; rally_eval serves
# the balls of `evaluate`'s seeds through /sim/launch_ball and scores each rally. The JSON has
# `evaluate`'s fields plus `world` (the setting) and the player's timing; Table IV of `paper_tables`
# reads results/sim2sim_*.json. Needs `source ros2_ws/install/setup.bash`.
set -eo pipefail
cd "$(dirname "$0")/.."
ACTOR=ros2_ws/src/stylepong_policy/models/amp_actor.pt
SEEDS=10
FIRST_SEED=1000
BALLS=20
JSON=results/sim2sim_ros.json
while [ $# -gt 0 ]; do
  case "$1" in
    --actor) ACTOR=$2; shift 2 ;;
    --seeds) SEEDS=$2; shift 2 ;;
    --first-seed) FIRST_SEED=$2; shift 2 ;;
    --balls) BALLS=$2; shift 2 ;;
    --json) JSON=$2; shift 2 ;;
    *) echo "sim2sim: unknown argument $1" >&2; exit 2 ;;
  esac
done
[ -f "${ACTOR%.pt}.onnx" ] || { echo "sim2sim: ${ACTOR%.pt}.onnx is missing (python3 -m stylepong_policy.rl.export --onnx $ACTOR)" >&2; exit 2; }
SENSING="$(ros2 pkg prefix stylepong_sim)/share/stylepong_sim/config/realistic_sensing.yaml"
LOGS=$(mktemp -d /tmp/sim2sim.XXXXXX)
export ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-$((RANDOM % 100 + 1))}
source tools/node_group.sh
echo "[sim2sim] $ACTOR through ROS: ur5_sim (realistic sensing) + player + rally_eval, seeds $FIRST_SEED.. x$SEEDS, $BALLS balls each; logs in $LOGS"
start_node "$LOGS/ur5_sim.log" ros2 run stylepong_sim ur5_sim --ros-args --params-file "$SENSING"
start_node "$LOGS/player.log" ros2 run stylepong_player player --ros-args -p actor:="$PWD/$ACTOR" -p use_sim_time:=true
mkdir -p "$(dirname "$JSON")"
ros2 run stylepong_sim rally_eval --balls "$BALLS" --first-seed "$FIRST_SEED" --seeds "$SEEDS" --speed all \
  --json "$JSON.part" 2>"$LOGS/rally_eval.err" | tee "$LOGS/rally_eval.log" | grep '^seed' | sed 's/^/[sim2sim]   /'
stop_nodes
python3 - "$JSON.part" "$JSON" "$ACTOR" <<'PY'
import json
import pathlib
import sys

part, out, actor = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2]), sys.argv[3]
result = json.loads(part.read_text())
result['world'] = ('ur5_sim (MuJoCo cell) through ROS: player (ONNX) + rally_eval, realistic sensing '
                   '(config/realistic_sensing.yaml), wall-clock paced')
result['actor'] = actor
out.write_text(json.dumps(result, indent=2) + '\n')
part.unlink()
print(f"[sim2sim] success rate {result['success_rate']:.3f} over {result['balls']} balls, hit rate "
      f"{result['hit_rate']:.3f}, failures {result['failures']}; written to {out}")
PY
