#!/usr/bin/env bash
# The recipe on styles it never saw: learn_style on every demonstration set in demonstrations/ (defaults,
# the same config for each), then the style confusion matrix (every actor's DTW distance to every set's
# clips, normalised by PPO's) written to results/, and from the same evaluations each learned style's
# report, its PNGs and its actor.onnx in results/styles/<set>/.
#
#   tools/style_sets.sh                  learn every set not yet learned (runs/style_<set>, 60 min each; a run
#                                        that was stopped resumes), then the matrix of those runs' actors
#   tools/style_sets.sh --matrix-only    the matrix of the learned styles shipped in the skill library
#                                        (models/skills/<set>.pt, put there by ship_skill): results/ as kept
#
# Needs the workspace built (make setup). The matrix evaluates every actor on seeds 1000-1009 x 200 balls.
set -eo pipefail
cd "$(dirname "$0")/.."
set +u
# shellcheck disable=SC1091
source ros2_ws/install/setup.bash
set -u
MODELS=ros2_ws/src/stylepong_policy/models
SETS=()
for dir in demonstrations/*/; do SETS+=("$(basename "$dir")"); done

if [ "${1:-}" != "--matrix-only" ]; then
  for set in "${SETS[@]}"; do
    run=runs/style_$set
    if [ ! -f "$run/report.md" ]; then
      resume=(); [ -f "$run/learn_style.json" ] && resume=(--resume)
      ros2 run stylepong_policy learn_style "demonstrations/$set" --out "$run" "${resume[@]}"
    fi
  done
fi

actors=(--actor "shipped=$MODELS/amp_actor.pt")
sets=(--set "shipped=ros2_ws/bags")
for set in "${SETS[@]}"; do
  # The skill is the learned network as shipped (style_confusion exports it: the actor's very actions).
  actor=$MODELS/skills/$set.pt
  [ "${1:-}" != "--matrix-only" ] && actor=runs/style_$set/actor.pt
  [ -f "$actor" ] && actors+=(--actor "$set=$actor")
  sets+=(--set "$set=demonstrations/$set")
done
ros2 run stylepong_policy style_confusion "${actors[@]}" "${sets[@]}" --baseline "$MODELS/ppo_actor.pt" \
  --seeds 10 --first-seed 1000 --balls 200 --out results
