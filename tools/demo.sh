#!/usr/bin/env bash
# `make demo`: the pipeline end to end in simulation, saying what each step did: record one
# demonstration clip by kinesthetic teaching, build the reference-motion dataset, and play the shipped
# policy through ROS (player + rally_eval in ur5_sim) with a video of the rally. Everything it writes goes
# to runs/demo/. ACTOR=<name>.pt make demo plays another exported actor.
set -eo pipefail
cd "$(dirname "$0")/.."
echo "[demo] loading the UR5 + paddle model in Pinocchio and MuJoCo"
python3 - <<'PY'
import mujoco
import numpy as np
import pinocchio as pin
from stylepong_description import robot_model as rm

model = rm.pinocchio_model()
data = model.createData()
pin.framesForwardKinematics(model, data, np.zeros(rm.NUM_JOINTS))
centre = data.oMf[model.getFrameId(rm.PADDLE_CENTRE_FRAME)].translation
mj = rm.mujoco_model()
print(f'[demo] {len(rm.JOINT_NAMES)} joints {", ".join(rm.JOINT_NAMES)}; total mass {sum(i.mass for i in model.inertias):.3f} kg '
      f'(paddle {rm.PADDLE.mass_kg:.3f} kg); paddle centre at q = 0: {np.round(centre, 4).tolist()} m in base_link; '
      f'MuJoCo: {mj.nbody} bodies, {mj.ngeom} geoms')
PY

# One demonstration clip end to end: ur5_sim + drag_teach + recorder, the virtual teacher dragging the arm.
DEMO_DIR=runs/demo
echo "[demo] recording one forward stroke: ur5_sim + drag_teach + recorder + virtual_teacher (under a minute)"
tools/record_demos.sh --out "$DEMO_DIR" forward
BAG=$(ls -d "$DEMO_DIR"/forward_* | sort | tail -n 1)
python3 - "$BAG" <<'PY'
import pathlib
import sys

import numpy as np
import yaml
from rosbags.highlevel import AnyReader

from stylepong_description import robot_model as rm
from stylepong_sim.teaching.teacher import CellKinematics

bag = pathlib.Path(sys.argv[1])
kinematics = CellKinematics()
tool = kinematics.frame_id(rm.TOOL_FRAME)
with AnyReader([bag]) as reader:
    connections = [c for c in reader.connections if c.topic == '/joint_states']
    stamps, positions = [], []
    for connection, _, raw in reader.messages(connections=connections):
        msg = reader.deserialize(raw, connection.msgtype)
        index = [list(msg.name).index(n) for n in rm.JOINT_NAMES]
        stamps.append(msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9)
        positions.append(kinematics.pose(np.asarray(msg.position)[index], tool).translation)
stamps, positions = np.array(stamps), np.array(positions)
ahead = np.searchsorted(stamps, stamps + 0.02)
valid = ahead < len(stamps)
speed = np.linalg.norm(positions[ahead[valid]] - positions[valid], axis=1) / (stamps[ahead[valid]] - stamps[valid])
label = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']['custom_data']['label']
travel = np.linalg.norm(np.diff(positions, axis=0), axis=1).sum()
print(f'[demo] clip {bag}: label {label!r}, {len(stamps)} joint states over {stamps[-1] - stamps[0]:.2f} s (sim time), '
      f'tool0 travelled {travel:.2f} m, peak speed {speed.max():.2f} m/s')
PY
echo "[demo] the bag is in $BAG (read it with rosbags or the mcap tools; the seven shipped clips are in ros2_ws/bags)"

# The training bridge: the new clip and the seven shipped ones -> 60 Hz reference motions, x2/x3/x5.
echo "[demo] building the reference-motion dataset from $BAG and the shipped clips in ros2_ws/bags"
ros2 run stylepong_policy build_dataset "$BAG" ros2_ws/bags -o "$DEMO_DIR/dataset.npz" --plot "$DEMO_DIR/dataset.png" \
  | grep '^wrote .*clips' | sed 's/^/[demo] /'
echo "[demo] dataset in $DEMO_DIR/dataset.npz, its clips plotted in $DEMO_DIR/dataset.png"

# The shipped actor playing through ROS: ur5_sim (recording an MP4) + player (ONNX, on the cell's clock) +
# rally_eval serving 20 evaluation balls. ACTOR is the exported actor (<name>.pt; the .onnx beside it is run).
ACTOR=${ACTOR:-ros2_ws/src/stylepong_policy/models/amp_actor.pt}   # the shipped style actor
BALLS=${BALLS:-20}
LOGS="$DEMO_DIR/logs"
mkdir -p "$LOGS"
if [ ! -f "${ACTOR%.pt}.onnx" ]; then
  echo "[demo] writing ${ACTOR%.pt}.onnx for the player"
  python3 -m stylepong_policy.rl.export --onnx "$ACTOR" | sed 's/^/[demo] /'
fi
export ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-$((RANDOM % 100 + 1))}
# ur5_sim finishes the MP4 on Ctrl-C: give it time.
NODE_GRACE_S=15
source tools/node_group.sh
echo "[demo] playing $ACTOR through ROS: ur5_sim + ball_estimator + player + rally_eval, $BALLS balls of the first evaluation seed (about $((BALLS * 5 / 60 + 1)) min)"
# max_lag_s: when rendering or a busy machine holds the cell back, it runs slower than real time rather
# than catching up in bursts that the player's commands could not reach in time.
start_node "$LOGS/ur5_sim.log" ros2 run stylepong_sim ur5_sim --ros-args -p record_video:="$DEMO_DIR/rally.mp4" -p max_lag_s:=0.01 \
  -p video_width:=480 -p video_height:=352 -p video_fps:=25.0
# The cell's tracker reports positions only, as a real one does; ball_estimator gives the player the ball's state
# (it runs on the detections' stamps, so it needs no /clock).
start_node "$LOGS/ball_estimator.log" ros2 run stylepong_player ball_estimator
start_node "$LOGS/player.log" ros2 run stylepong_policy player --ros-args -p actor:="$PWD/$ACTOR" -p use_sim_time:=true
# The browser viewer on the same graph: the arm, the ball and the plots, live while the rally is played.
start_node "$LOGS/viewer.log" ros2 run stylepong_viz viewer --web-port "${VIEWER_PORT:-9090}" --grpc-port "${VIEWER_GRPC_PORT:-9876}"
for _ in $(seq 150); do grep -q '^viewer: open' "$LOGS/viewer.log" && break; sleep 0.1; done
if grep -q '^viewer: open' "$LOGS/viewer.log"; then
  echo "[demo] watch it live in a browser: $(grep -o 'http://[^ ]*' "$LOGS/viewer.log" | head -n 1)"
else
  echo "[demo] the viewer did not start (see $LOGS/viewer.log); the rally goes on without it"
fi
ros2 run stylepong_sim rally_eval --balls "$BALLS" --seeds 1 --speed all \
  --json "$DEMO_DIR/rally.json" 2>"$LOGS/rally_eval.err" | tee "$LOGS/rally_eval.log" | grep '^seed' | sed 's/^/[demo]   /'
stop_nodes
python3 - "$DEMO_DIR/rally.json" <<'PY'
import json
import sys

r = json.load(open(sys.argv[1]))
p = r['player_status']
print(f"[demo] success rate {r['success_rate']:.3f} ({round(r['success_rate'] * r['balls'])}/{r['balls']} returned), "
      f"hit rate {r['hit_rate']:.3f}, failures {r['failures']} (through ROS in ur5_sim)")
print(f"[demo] player: period p99 jitter {p['period_ms'].get('jitter_p99')} ms, ball-to-command latency p99 "
      f"{p['latency_ms'].get('p99')} ms, inference p50 {p['inference_ms'].get('p50')} ms ({p['backend']})")
PY
echo "[demo] outputs: demonstration clip $BAG; dataset $DEMO_DIR/dataset.npz (plot $DEMO_DIR/dataset.png);"
echo "[demo]   rally result $DEMO_DIR/rally.json; rally video $DEMO_DIR/rally.mp4; node logs $LOGS"
echo "[demo] next, a style of your own: learn one from the clip just recorded (a folder of your labelled clips"
echo "[demo]   works the same), then play it (learn_style takes about 60 min on a 2-core CPU):"
echo "[demo]   ros2 run stylepong_policy learn_style $BAG --out runs/my_style"
echo "[demo]   ros2 run stylepong_policy player --ros-args -p actor:=runs/my_style/actor.onnx"
