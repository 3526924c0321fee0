#!/usr/bin/env bash
# The recipe on drawn styles nobody tuned it for: learn_style on every held-out style of a drawn_styles split
# (defaults, the same config for each), the style confusion matrix over the shipped set and the held-out sets
# with their learned actors (normalised by PPO's), then results/style_generalisation.md and .json: a row per
# held-out set against learn_style's targets, how many met every target, the matrix, and how many times the
# held-out figures were looked at (style_generalisation counts it).
#
#   tools/style_generalisation.sh SPLIT_DIR SETS_DIR
#       SPLIT_DIR: what `tools/drawn_styles.py generate --out SPLIT_DIR` wrote (split.json, the style files);
#       SETS_DIR: what `tools/drawn_styles.py record --which heldout --out SETS_DIR` recorded (SETS_DIR/<style>/).
#       Each held-out style is learned into runs/heldout/<style> (60 min each; a stopped run resumes, a
#       finished one is kept), the matrix goes to runs/heldout/confusion, the table to results/.
#
# Needs the workspace built (make setup). The matrix evaluates every actor on seeds 1000-1009 x 200 balls.
# Held-out sets are reported once: each rerun that changes their figures is counted as another look.
set -eo pipefail
if [ $# -ne 2 ]; then
  echo "usage: $0 SPLIT_DIR SETS_DIR (what tools/drawn_styles.py generate and record --which heldout wrote)" >&2
  exit 2
fi
ROOT=$(cd "$(dirname "$0")/.." && pwd)
# The arguments as given from here, relative to the checkout that the script works in: the paths the table
# and the matrix record stay free of this machine's folders.
SPLIT=$(realpath -m --relative-to="$ROOT" "$1/split.json")
SETS_DIR=$(realpath -m --relative-to="$ROOT" "$2")
cd "$ROOT"
set +u
# shellcheck disable=SC1091
source ros2_ws/install/setup.bash
set -u
MODELS=ros2_ws/src/stylepong_policy/models
RUNS=runs/heldout
# The held-out half only: the tuning styles are never learned or evaluated here. Read by the table's own
# reader, so that a split it would refuse stops the script before hours of learning (one line, status 2).
names=$(python3 - "$SPLIT" <<'EOF'
import pathlib
import sys

from stylepong_policy.reports import style_generalisation

try:
    print('\n'.join(style_generalisation.heldout_sets(pathlib.Path(sys.argv[1]))))
except style_generalisation.InputError as error:
    print(f'style_generalisation.sh: {error}', file=sys.stderr)
    sys.exit(2)
EOF
)
if [ -z "$names" ]; then echo "style_generalisation.sh: $SPLIT holds no held-out style" >&2; exit 2; fi
mapfile -t HELDOUT <<<"$names"

# A run is finished when learn_style recorded its last stage (report), as style_generalisation reads it.
finished() {
  [ -f "$1/learn_style.json" ] &&
    python3 -c 'import json, sys; sys.exit("report" not in json.load(open(sys.argv[1])).get("stages", {}))' \
      "$1/learn_style.json"
}

for style in "${HELDOUT[@]}"; do
  run=$RUNS/$style
  if finished "$run"; then continue; fi
  resume=(); [ -f "$run/learn_style.json" ] && resume=(--resume)
  status=0
  ros2 run stylepong_policy learn_style "$SETS_DIR/$style" --out "$run" "${resume[@]}" || status=$?
  # A style whose run fails is listed as missing or unfinished in the table, not dropped; Ctrl-C stops all.
  if [ "$status" -eq 130 ]; then exit 130; fi
  if [ "$status" -ne 0 ]; then
    echo "style_generalisation.sh: learn_style on $style ended with status $status" >&2
  fi
done

actors=(--actor "shipped=$MODELS/amp_actor.pt")
sets=(--set "shipped=ros2_ws/bags")
for style in "${HELDOUT[@]}"; do
  # Only a finished run's actor: an unfinished one's actor.pt may be a stage short of its evaluation.
  if finished "$RUNS/$style"; then actors+=(--actor "$style=$RUNS/$style/actor.pt"); fi
  if [ -d "$SETS_DIR/$style" ]; then sets+=(--set "$style=$SETS_DIR/$style"); fi
done
ros2 run stylepong_policy style_confusion "${actors[@]}" "${sets[@]}" --baseline "$MODELS/ppo_actor.pt" \
  --seeds 10 --first-seed 1000 --balls 200 --out "$RUNS/confusion"
ros2 run stylepong_policy style_generalisation --split "$SPLIT" --runs "$RUNS" \
  --confusion "$RUNS/confusion/style_confusion.json" --out results
