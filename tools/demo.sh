#!/usr/bin/env bash
# `make demo`: run the parts of the pipeline that exist, saying what each step did.
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
