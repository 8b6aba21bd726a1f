#!/usr/bin/env bash
# Command-line values refused before any instrument or file is touched, each message naming the
# option and what was expected (the help texts say the same): camera grab (an --out holding
# earlier frames, a NaN or negative frame rate or exposure, a zero timeout), hall record (an
# existing recording or its clock file as --out, --res-xy without --gain), experiment table1 (a
# row outside 1..6), sessions show (--events 0); any number on any command line that is not finite
# or not a plain decimal integer; --ui-bind without --ui; demo's existing --store, negative --seed;
# mock camera's sensor size with a simulated scene. Nothing listens in this test's network namespace
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
refuse grab_rate_nan "--frame-rate: 'nan': expected a finite number" \
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

# Every number on any command line (one check in main.cc, before the command runs): floating-point
# values finite, integers plain decimal (CLI11 alone reads "0100" as 64 and "0x10" as 16).
refuse table2_inf "--actual-s: 'inf': expected a finite number" \
  experiment table2 --actual-s inf
refuse table2_neg_inf "--background-s: '-INF': expected a finite number" \
  experiment table2 --background-s -INF
refuse grab_count_octal "--count: '010': expected a decimal integer" \
  camera grab --device v4l2:/dev/msmcal-no-such-camera --count 010 --out "$dir/new4"
refuse hall_rate_hex "--rate: '0x10': expected a decimal integer" \
  hall record --device /dev/msmcal-no-such-mcu --seconds 1 --out "$dir/d.csv" --rate 0x10
test ! -e "$dir/new4" && test ! -e "$dir/d.csv"
# An unsigned option takes no sign (CLI11 alone reads -1 as 18446744073709551615), and no value
# beyond 64 bits (it would saturate).
refuse solve_seed_negative "--seed: '-1': expected a decimal integer >= 0" \
  solve "$dir/none" --seed -1
refuse solve_seed_overflow "--seed: '99999999999999999999': expected an integer within 64 bits" \
  solve "$dir/none" --seed 99999999999999999999
# --ui-bind alone would be ignored (the live view only runs with --ui).
refuse ui_bind_alone "--ui-bind requires --ui" demo --ui-bind 0.0.0.0 --out "$dir/demo"
test ! -e "$dir/demo"
# demo: an existing --store is refused before the run (it was found only after it), and a
# negative --seed is refused (it silently meant the config's seed).
mkdir "$dir/store"
refuse demo_store_exists "--store: $dir/store already exists" \
  demo --store "$dir/store" --out "$dir/demo"
refuse demo_seed_negative "--seed: '-3': expected a decimal integer >= 0" demo --seed -3 --out "$dir/demo"
test ! -e "$dir/demo"
# mock camera: a sensor size with a simulated scene would be ignored (the simulator's camera sets
# it); refused before the simulator configuration is even read.
refuse mock_camera_sim_size "--sensor-width/--sensor-height: not with --scene sim:" \
  mock camera --scene sim:/nonexistent.yaml --sensor-width 640
echo PASS
