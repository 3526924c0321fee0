#!/usr/bin/env bash
# Record demonstration clips through the real pipeline: ur5_sim + drag_teach + recorder, and the
# virtual teacher playing the person for each swing (one labelled rosbag2 bag per clip).
#
#   tools/record_demos.sh                      the seven shipped clips into ros2_ws/bags
#                                              (forward x3, leftward x2, rightward x2, interleaved)
#   tools/record_demos.sh --out DIR SWING...   the given swings (forward|leftward|rightward) into DIR
#
# Each clip is another take: clip N (1-based, in the order recorded) gets the virtual teacher's seed
# N + SEED_OFFSET (default 0), so the shipped set is seeds 1-7 (forward 1, 4, 7; leftward 2, 5;
# rightward 3, 6) and a re-recording gives the same strokes. Another SEED_OFFSET gives other takes.
# BLADE_PITCH_RAD (default 0.6, the shipped clips; 0.0 keeps the blade upright) is how far the teacher
# opens the blade through each stroke (teacher.TeacherConfig.blade_pitch_rad), SIDE_TURN_RAD (default 0.0)
# how far it turns the leftward and rightward strokes further to their side (side_turn_rad), SIDE_REACH_M
# (default 0.0) how far it carries them further to their side with the arm reaching out (side_reach_m; at
# most 0.1 leftward, 0.3 rightward). Write them with a decimal point: they are double parameters.
#
# Another person's style: STROKES_FILE (default none: the shipped strokes) is a style's hand-made key poses,
# a YAML file or a name in ros2_ws/src/stylepong_sim/config/styles (long, compact, wristy; the teacher's
# strokes_file, stylepong_sim/teaching/stroke_styles.py), each take checked before it is dragged. BACKSWING_S and
# FORWARD_SWING_S (default 0.8 and 1.6) are the tempo: a careful drag of a real UR5 (about 1 rad/s at the
# fastest joint) takes about twice as long. JOINT_STATE_RATE_HZ (default 500, the shipped clips) is the
# simulated arm's /joint_states rate: 125 records clips as a CB3 UR driver does (ur5_sim's
# joint_state_rate_hz; drag_teach keeps its own control rate and holds the last state between them).
#
#   STROKES_FILE=long BACKSWING_S=1.6 FORWARD_SWING_S=3.0 JOINT_STATE_RATE_HZ=125 \
#     tools/record_demos.sh --out demonstrations/long forward leftward rightward forward leftward rightward forward
#
# The cell runs at a quarter of real time (REAL_TIME_FACTOR) and drag_teach and the teacher follow its
# clock (/clock): on a busy machine the Python nodes still get their turn every 2 ms of simulated time,
# and nothing gets out of step with the arm. Needs the workspace built (make setup). Uses ROS_DOMAIN_ID
# if set, else a random one (printed).
set -eo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
OUT=$ROOT/ros2_ws/bags
if [ "${1:-}" = "--out" ]; then
  OUT=$(realpath -m "$2")
  shift 2
fi
SWINGS=("$@")
[ ${#SWINGS[@]} -gt 0 ] || SWINGS=(forward leftward rightward forward leftward rightward forward)
for swing in "${SWINGS[@]}"; do
  case $swing in forward|leftward|rightward) ;; *) echo "[record] unknown swing '$swing'" >&2; exit 2;; esac
done

set +u
# shellcheck disable=SC1091
source "$ROOT/ros2_ws/install/setup.bash"
export ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-$((RANDOM % 100 + 1))}
export ROS_AUTOMATIC_DISCOVERY_RANGE=${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}
REAL_TIME_FACTOR=${REAL_TIME_FACTOR:-0.25}
SEED_OFFSET=${SEED_OFFSET:-0}
BLADE_PITCH_RAD=${BLADE_PITCH_RAD:-0.6}
SIDE_TURN_RAD=${SIDE_TURN_RAD:-0.0}
SIDE_REACH_M=${SIDE_REACH_M:-0.0}
STROKES_FILE=${STROKES_FILE:-}
BACKSWING_S=${BACKSWING_S:-0.8}
FORWARD_SWING_S=${FORWARD_SWING_S:-1.6}
JOINT_STATE_RATE_HZ=${JOINT_STATE_RATE_HZ:-500.0}
STYLE_ARGS=()   # an empty string parameter does not survive the command line: passed only when set
[ -z "$STROKES_FILE" ] || STYLE_ARGS=(-p strokes_file:="$STROKES_FILE")
mkdir -p "$OUT"
LOGS=$(mktemp -d -t stylepong_record.XXXXXX)
say() { printf '[record] %s\n' "$*"; }

NODE_GRACE_S=5
source "$(dirname "$0")/node_group.sh"

say "ROS_DOMAIN_ID=$ROS_DOMAIN_ID, node logs in $LOGS"
start_node "$LOGS/ur5_sim.log" ros2 run stylepong_sim ur5_sim --ros-args -p real_time_factor:="$REAL_TIME_FACTOR" \
  -p joint_state_rate_hz:="$JOINT_STATE_RATE_HZ"
start_node "$LOGS/drag_teach.log" ros2 run stylepong_fdcc drag_teach --ros-args -p use_sim_time:=true
start_node "$LOGS/recorder.log" ros2 run stylepong_recording recorder --ros-args -p output_dir:="$OUT"
say "started ur5_sim (real_time_factor $REAL_TIME_FACTOR, joint states at $JOINT_STATE_RATE_HZ Hz), drag_teach and the recorder (clips into $OUT)"

recorded=()
clip=0
for swing in "${SWINGS[@]}"; do
  clip=$((clip + 1))
  seed=$((clip + SEED_OFFSET))
  log=$LOGS/virtual_teacher_${clip}_$swing.log
  say "teaching a $swing stroke (clip $clip, seed $seed)"
  if ! ros2 run stylepong_sim virtual_teacher --ros-args -p swing:="$swing" -p seed:="$seed" -p use_sim_time:=true \
      -p blade_pitch_rad:="$BLADE_PITCH_RAD" -p side_turn_rad:="$SIDE_TURN_RAD" -p side_reach_m:="$SIDE_REACH_M" \
      -p backswing_s:="$BACKSWING_S" -p forward_swing_s:="$FORWARD_SWING_S" "${STYLE_ARGS[@]}" \
      >"$log" 2>&1; then
    say "the $swing stroke failed; its log:"
    tail -n 20 "$log" >&2
    exit 1
  fi
  bag=$(sed -n "s/.*recording '$swing' into \(.*\)$/\1/p" "$log" | tail -n 1)
  say "recorded $bag (seed $seed)"
  recorded+=("$bag")
done
stop_nodes
# The recorder writes an uncompressed chunk per flush (little lost in a crash); the closed clips are
# rewritten with zstd-compressed chunks, as the shipped ones are (about 2.4 times smaller).
ros2 run stylepong_recording compress_bag "${recorded[@]}"
say "${#recorded[@]} clip(s) in $OUT"
printf '%s\n' "${recorded[@]}" >"$LOGS/recorded.txt"
