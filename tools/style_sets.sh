#!/usr/bin/env bash
# The recipe on styles it never saw: learn_style on every demonstration set in demonstrations/ (defaults,
# the same config for each), the learned actors kept in results/styles/, and the style confusion matrix
# (every actor's DTW distance to every set's clips, normalised by PPO's) written to results/.
#
#   tools/style_sets.sh                  learn every set not yet learned (runs/style_<set>, 60 min each; a run
#                                        that was stopped resumes), then the matrix
#   tools/style_sets.sh --matrix-only    the matrix from the actors already in results/styles/
#
# Needs the workspace built (make setup). The matrix evaluates every actor on seeds 1000-1009 x 200 balls.
set -eo pipefail
cd "$(dirname "$0")/.."
set +u
# shellcheck disable=SC1091
source ros2_ws/install/setup.bash
set -u
MODELS=ros2_ws/src/stylepong_policy/models
STYLES=results/styles
mkdir -p "$STYLES"
SETS=()
for dir in demonstrations/*/; do SETS+=("$(basename "$dir")"); done

if [ "${1:-}" != "--matrix-only" ]; then
  for set in "${SETS[@]}"; do
    run=runs/style_$set
    if [ ! -f "$run/report.md" ]; then
      resume=(); [ -f "$run/learn_style.json" ] && resume=(--resume)
      ros2 run stylepong_policy learn_style "demonstrations/$set" --out "$run" "${resume[@]}"
    fi
    mkdir -p "$STYLES/$set"
    # The actor and its report's figures (report.json; report.md and its PNGs stay in the run: 1.6 MB a set).
    cp "$run"/actor.pt "$run"/actor.json "$run"/report.json "$STYLES/$set/"
  done
fi

actors=(--actor "shipped=$MODELS/amp_actor.pt")
sets=(--set "shipped=ros2_ws/bags")
for set in "${SETS[@]}"; do
  [ -f "$STYLES/$set/actor.pt" ] && actors+=(--actor "$set=$STYLES/$set/actor.pt")
  sets+=(--set "$set=demonstrations/$set")
done
ros2 run stylepong_policy style_confusion "${actors[@]}" "${sets[@]}" --baseline "$MODELS/ppo_actor.pt" \
  --seeds 10 --first-seed 1000 --balls 200 --out results
