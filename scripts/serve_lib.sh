# Sourced by the A/B scripts: start `tre serve` on 127.0.0.1:$PORT and wait until it is ready,
# and stop it again. Run from the repository root (the models are ./models).
#
#   serve_up BIN LOG [tre serve options]   # sets SERVE_PID; fails if the server exits or is
#                                          # not ready within 180 s (its stderr is in LOG)
#   serve_down                             # stops it and waits for it

serve_up() {
  local bin=$1 log=$2
  shift 2
  "$bin" serve --addr "127.0.0.1:$PORT" --models models "$@" >/dev/null 2>"$log" &
  SERVE_PID=$!
  for _ in $(seq 1 900); do
    curl -sf "http://127.0.0.1:$PORT/readyz" >/dev/null && return 0
    if ! kill -0 "$SERVE_PID" 2>/dev/null; then
      echo "tre serve exited before it was ready; see $log" >&2
      return 1
    fi
    sleep 0.2
  done
  echo "tre serve not ready within 180 s; see $log" >&2
  return 1
}

serve_down() {
  kill "$SERVE_PID" 2>/dev/null || true
  wait "$SERVE_PID" 2>/dev/null || true
}
