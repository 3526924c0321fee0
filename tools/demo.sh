#!/usr/bin/env bash
# `make demo`: the pipeline end to end in simulation, saying what each step did: record one
# demonstration clip by kinesthetic teaching, build the reference-motion dataset, and evaluate the
# shipped policy with a video of its strokes. Everything it writes goes to runs/demo/.
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
from stylepong_sim.teacher import CellKinematics

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

# The shipped PPO baseline actor returning balls in the batched world, with a video of a few strokes.
ACTOR=ros2_ws/src/stylepong_policy/models/ppo_actor.pt
echo "[demo] evaluating the shipped actor $ACTOR: 2 seeds x 200 balls, all speeds, rendering 4 strokes"
ros2 run stylepong_policy evaluate --actor "$ACTOR" --seeds 2 --first-seed 1000 --balls 200 --speed all \
  --json "$DEMO_DIR/evaluation.json" --video "$DEMO_DIR/strokes.mp4" | grep '^seed'
python3 - "$DEMO_DIR/evaluation.json" <<'PY'
import json
import sys

result = json.load(open(sys.argv[1]))
print(f"[demo] success rate {result['success_rate']:.3f}, hit rate {result['hit_rate']:.3f} over {result['balls']} balls "
      f"(results in {sys.argv[1]}); the strokes are in {sys.argv[1].rsplit('/', 1)[0]}/strokes.mp4")
PY
