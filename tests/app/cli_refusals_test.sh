#!/usr/bin/env bash
# Command-line values refused before any instrument or file is touched, each message naming the
# option and what was expected (the help texts say the same): camera grab (an --out holding
# earlier frames, a NaN or negative frame rate or exposure, a zero timeout), hall record (an
# existing recording or its clock file as --out, --res-xy without --gain), experiment table1 (a
# row outside 1..6), sessions show (--events 0). Nothing listens in this test's network namespace
# and the devices named do not exist: a refusal that came after opening would fail differently.
set -euo pipefail
msmcal="$1"
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT

refuse() {  # name, expected message (fixed string), command...
  local name="$1" expected="$2"
  shift 2
  if "$msmcal" "$@" > "$dir/$name.out" 2>&1; then
    echo "FAIL: $name: accepted: $*"; cat "$dir/$name.out"; exit 1
  fi
  grep -q -F -- "$expected" "$dir/$name.out" || {
    cat "$dir/$name.out"; echo "FAIL: $name: no '$expected'"; exit 1; }
  echo "ok: $name: $(grep -F -- "$expected" "$dir/$name.out" | head -1)"
}

mkdir -p "$dir/frames"
echo old > "$dir/frames/000000.png"
grab=(camera grab --device v4l2:/dev/msmcal-no-such-camera --count 1)
refuse grab_nonempty "--out $dir/frames: exists and is not an empty folder" \
  "${grab[@]}" --out "$dir/frames"
test "$(cat "$dir/frames/000000.png")" = old
refuse grab_rate_nan "--frame-rate = nan: must be >= 0 Hz" \
  "${grab[@]}" --out "$dir/new1" --frame-rate nan
refuse grab_exposure_neg "--exposure-us = -5: must be >= 0 us" \
  "${grab[@]}" --out "$dir/new2" --exposure-us -5
refuse grab_timeout_zero "--timeout-ms" "${grab[@]}" --out "$dir/new3" --timeout-ms 0
test ! -e "$dir/new1" && test ! -e "$dir/new2" && test ! -e "$dir/new3"

echo "mcu_time_us,bx_uT,by_uT,bz_uT" > "$dir/actual.csv"
refuse record_exists "--out $dir/actual.csv: $dir/actual.csv exists" \
  hall record --device /dev/msmcal-no-such-mcu --seconds 1 --out "$dir/actual.csv"
echo "mcu_time_us" > "$dir/b_clock.csv"
refuse record_clock_exists "$dir/b_clock.csv exists" \
  hall record --device /dev/msmcal-no-such-mcu --seconds 1 --out "$dir/b.csv"
test ! -e "$dir/b.csv"
refuse record_res_without_gain "--gain" \
  hall record --device /dev/msmcal-no-such-mcu --seconds 1 --out "$dir/c.csv" --res-xy 1
test ! -e "$dir/c.csv"

refuse table1_rows "--rows" experiment table1 --rows 7
refuse events_zero "--events" sessions show "$dir/none" --events 0
echo PASS
