#!/usr/bin/env bash
# `msmcal camera grab` through the Aravis driver against the mock GigE Vision camera (own network
# namespace): 3 frames written as PNGs of the asked size; the same --out again is refused before
# the camera is opened (no earlier frame overwritten); a camera that stops streaming after 2
# frames (--fault lost@2) ends the grab with an error naming the waits, not a hang: exactly 2
# frames written (the mock sends exactly N; CI once saw 3 when its fault raced a second thread),
# waits of 1 s for frames due every 100 ms so that a loaded machine does not end the grab early.
set -euo pipefail
msmcal="$1"
dir=$(mktemp -d)
cam=
trap '[ -n "$cam" ] && kill "$cam" 2>/dev/null; rm -rf "$dir"' EXIT

serve() {  # options... : starts the mock camera, returns once it says it is ready
  coproc CAM { exec "$msmcal" mock camera --address 127.0.0.1 --sensor-width 320 \
    --sensor-height 240 "$@" 2>&1; }
  cam=$CAM_PID
  local line
  while IFS= read -r -t 30 line <&"${CAM[0]}"; do
    [[ "$line" == "camera ready at 127.0.0.1"* ]] && return 0
  done
  echo "FAIL: mock camera not ready"; exit 1
}
stop() { kill "$cam"; wait "$cam" 2>/dev/null || true; cam=; }

serve --frame-rate 20
"$msmcal" camera grab --device 127.0.0.1 --count 3 --out "$dir/g1" --width 320 --height 240 \
  > "$dir/g1.out" 2>&1 || { cat "$dir/g1.out"; echo "FAIL: grab"; exit 1; }
grep -q "^grabbed 3, written 3, dropped 0, write errors 0" "$dir/g1.out" || {
  cat "$dir/g1.out"; exit 1; }
test "$(ls "$dir/g1" | wc -l)" -eq 3
/usr/bin/python3 - "$dir/g1" <<'PY'
import struct, sys, os
for f in sorted(os.listdir(sys.argv[1])):
    head = open(os.path.join(sys.argv[1], f), "rb").read(24)
    assert head[:8] == b"\x89PNG\r\n\x1a\n", f
    w, h = struct.unpack(">II", head[16:24])
    assert (w, h) == (320, 240), (f, w, h)
PY
sum1=$(cat "$dir"/g1/* | md5sum)
if "$msmcal" camera grab --device 127.0.0.1 --count 3 --out "$dir/g1" > "$dir/again.out" 2>&1; then
  echo "FAIL: grab into a folder holding frames"; exit 1
fi
grep -q -F "exists and is not an empty folder" "$dir/again.out"
test "$(cat "$dir"/g1/* | md5sum)" = "$sum1"
stop

serve --fault lost@2
if "$msmcal" camera grab --device 127.0.0.1 --count 5 --out "$dir/g2" --timeout-ms 1000 \
    --max-timeouts 2 > "$dir/lost.out" 2>&1; then
  cat "$dir/lost.out"; echo "FAIL: a lost camera's grab succeeded"; exit 1
fi
cat "$dir/lost.out"
grep -q -F "wrote 2 of 5 frames to $dir/g2: no frame in 2 waits of 1000 ms in a row" "$dir/lost.out"
stop
echo PASS
