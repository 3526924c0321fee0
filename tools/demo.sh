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
