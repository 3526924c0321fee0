#!/usr/bin/env bash
# The shipped PPO baseline, from nothing to models/: stage 1 (config/ppo.yaml, 1300 iterations), stage 2
# (config/ppo_stage2.yaml, the same run resumed up to 1700 iterations), the checkpoint chosen on
# validation seeds below 1000, and the chosen actor with its records copied into the package's models/.
#
#   tools/train_ppo_baseline.sh [RUN_DIR]       (default runs/ppo; about 1 h on 2 CPU cores)
#
# Needs `source ros2_ws/install/setup.bash`. Stopped at any point, the same command goes on from the
# run's last checkpoint; a finished stage is not run again.
set -euo pipefail
cd "$(dirname "$0")/.."
run=${1:-runs/ppo}
config=ros2_ws/src/stylepong_policy/config
stage1_iterations=1300   # config/ppo.yaml's runner.iterations

iterations_done() {
    python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["iterations"])' "$run/summary.json" 2>/dev/null || echo 0
}

train_stage() {
    local resume=()
    [ -f "$run/checkpoints/last.pt" ] && resume=(--resume)
    ros2 run stylepong_policy train --method ppo --out "$run" --config "$1" --no-progress --no-tensorboard "${resume[@]}"
}

if [ "$(iterations_done)" -lt "$stage1_iterations" ]; then
    train_stage "$config/ppo.yaml"
fi
train_stage "$config/ppo_stage2.yaml"
ros2 run stylepong_policy select_checkpoint --run "$run" --seeds 10 --first-seed 900 --balls 200 \
    --high-first-seed 950 --export "$run/selected/ppo_actor.pt"
ros2 run stylepong_policy ship_run --run "$run" --name ppo
