# Sourced by the tools that run a ROS graph (demo.sh, record_demos.sh, sim2sim.sh): start nodes in the
# background and stop them newest first (a recorder closes its bag, ur5_sim finishes its MP4, before the
# nodes they depend on go away), each with Ctrl-C and a grace period, then SIGKILL.
NODE_PIDS=()
NODE_GRACE_S=${NODE_GRACE_S:-10}

start_node() {  # start_node LOG COMMAND [ARGS...]
  local log=$1
  shift
  "$@" >"$log" 2>&1 &
  NODE_PIDS+=($!)
}

stop_nodes() {
  local i
  for (( i=${#NODE_PIDS[@]}-1; i>=0; i-- )); do
    kill -INT "${NODE_PIDS[i]}" 2>/dev/null || true
    for _ in $(seq $((NODE_GRACE_S * 10))); do kill -0 "${NODE_PIDS[i]}" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "${NODE_PIDS[i]}" 2>/dev/null || true
  done
  NODE_PIDS=()
}

trap stop_nodes EXIT
trap 'exit 130' INT TERM
