#!/usr/bin/env bash
# Rig sweeps (issue 20, docs/lab-path.md "Rig sweeps"): every point of a rig sweep is checked
# against the rig file's limits before anything starts. config/sweep-rig-example.yaml lists its 2
# points within config/rig.yaml's limits; a sweep whose second point drives the fast coil outside
# its frequency window, one whose amplitude exceeds max_vpp and one whose trigger density breaks
# the duty limit are refused naming the point, the field, the value and the limit, with nothing
# created and nothing contacted (the test runs in a network namespace where nothing listens).
# The simulated sweep's options are refused for a rig sweep (an unknown rig file field), and so is
# a console operator (nobody is at the rig), and --mcu without --rig. Running the points (with
# --mcu): cli.twin_rig_sweep. A rig sweep folder is reported by `msmcal report` and not continued
# without --rig.
set -euo pipefail
msmcal="$1"
src="$2"
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
rig="$src/config/rig.yaml"

"$msmcal" sweep "$src/config/sweep-rig-example.yaml" --rig "$rig" --out "$dir/ok" --list \
  > "$dir/list.out"
cat "$dir/list.out"
grep -q "^msmcal sweep: 2 rig points (2 axes x 1 repeats)" "$dir/list.out"
test "$(grep -c "ok (within the rig's limits)" "$dir/list.out")" -eq 2
test ! -e "$dir/ok"

refuse() {  # name, sweep text, patterns the message must contain...
  local name="$1" text="$2"
  shift 2
  printf '%s\n' "$text" > "$dir/$name.yaml"
  mkdir -p "$dir/ref"
  if "$msmcal" sweep "$dir/$name.yaml" --rig "$rig" --reference "$dir/ref" --out "$dir/$name" \
      ${extra:-} > "$dir/$name.out" 2>&1; then
    echo "FAIL: $name: expected a refusal"; cat "$dir/$name.out"; exit 1
  fi
  cat "$dir/$name.out"
  for pattern in "$@"; do
    grep -q -F -- "$pattern" "$dir/$name.out" || {
      echo "FAIL: $name: no '$pattern' in the refusal"; exit 1; }
  done
  # The line of the resolved document would mislead: the message names the point instead.
  if grep -q "with the point's values):[0-9]" "$dir/$name.out"; then
    echo "FAIL: $name: a line number of the resolved rig file in the refusal"; exit 1
  fi
  test ! -e "$dir/$name"
}
# A reference that is no session folder is refused before the points (nothing runs without it).
refuse noref 'axes: {generators.signals.drive.fast.frequency_hz: [205]}' \
  "--reference" "no session.yaml"
mkdir -p "$dir/ref/hall"
: > "$dir/ref/session.yaml"; : > "$dir/ref/camera.yaml"; : > "$dir/ref/hall/background.csv"
refuse window 'axes: {generators.signals.drive.fast.frequency_hz: [205, 230]}' \
  "generators.signals.drive.fast.frequency_hz = 230" "frequency_hz = 230" "[195, 215]"
refuse vpp 'axes: {generators.signals.drive.fast.amplitude_vpp: [2.0, 4.5]}' \
  "generators.signals.drive.fast.amplitude_vpp = 4.5" "4.5" "4"
refuse duty 'axes: {generators.signals.trigger.pulse_width_s: [1.0e-6, 1.0e-3]}' \
  "generators.signals.trigger.pulse_width_s = 1.0e-3" "max_duty"
refuse unknown 'axes: {mirror.fast.frequency_hz: [205]}' \
  "mirror.fast.frequency_hz: unknown rig file field"
# Nobody is at the rig during a rig sweep: no console operator.
extra="--operator console" refuse console 'axes: {generators.signals.drive.fast.frequency_hz: [205]}' \
  "--operator = 'console'" "hook:CMD"
# The simulated sweep is unchanged: no --rig, its own options.
"$msmcal" sweep "$src/config/sweep-example.yaml" --out "$dir/sim" --list > "$dir/sim.out"
grep -q "^msmcal sweep: 16 points" "$dir/sim.out" || { cat "$dir/sim.out"; exit 1; }
# --mcu (the twin's --hall-link, as session run --mcu) belongs to a rig sweep only.
if "$msmcal" sweep "$src/config/sweep-example.yaml" --out "$dir/simmcu" --mcu /tmp/twin-mcu \
    > "$dir/simmcu.out" 2>&1; then
  echo "FAIL: --mcu accepted without --rig"; cat "$dir/simmcu.out"; exit 1
fi
grep -q -F -- "--hook-timeout are for a rig sweep (--rig RIG)" "$dir/simmcu.out" || {
  cat "$dir/simmcu.out"; exit 1; }
test ! -e "$dir/simmcu"
# So does --hook-timeout (a simulated sweep has no hook: it would be ignored).
if "$msmcal" sweep "$src/config/sweep-example.yaml" --out "$dir/simhook" --hook-timeout 60 \
    > "$dir/simhook.out" 2>&1; then
  echo "FAIL: --hook-timeout accepted without --rig"; cat "$dir/simhook.out"; exit 1
fi
grep -q -F -- "--hook-timeout are for a rig sweep (--rig RIG)" "$dir/simhook.out" || {
  cat "$dir/simhook.out"; exit 1; }
test ! -e "$dir/simhook"
# A rig sweep's folder (sweep.yaml as the sweep stores it: base: holds every rig file field).
# `msmcal report` reads it as a rig sweep (the simulator's options refuse base.generators), and
# continuing it without --rig is refused with what it needs; nothing is run or written.
expect() {  # file, fixed string
  grep -q -F -- "$2" "$1" || { cat "$1"; echo "FAIL: no '$2' in $1"; exit 1; }
}
mkdir -p "$dir/rs"
{ echo 'axes: {generators.signals.drive.fast.amplitude_vpp: [2.0, 1.5]}'
  echo 'base:'
  sed 's/^/  /' "$rig"; } > "$dir/rs/sweep.yaml"
"$msmcal" report "$dir/rs" --quiet > "$dir/rs.out" 2>&1 || {
  cat "$dir/rs.out"; echo "FAIL: msmcal report on a rig sweep folder"; exit 1; }
cat "$dir/rs.out"
expect "$dir/rs.out" "sweep report: $dir/rs/report.html (0 of 2 point reports written)"
expect "$dir/rs/report.html" "fast.amplitude_vpp=1.5"
if "$msmcal" sweep --resume "$dir/rs" > "$dir/rsr.out" 2>&1; then
  echo "FAIL: a rig sweep continued without --rig"; cat "$dir/rsr.out"; exit 1
fi
cat "$dir/rsr.out"
expect "$dir/rsr.out" "holds a rig sweep"
expect "$dir/rsr.out" "--rig RIG --reference SESSION_DIR"
test ! -e "$dir/rs/sweep_state.json"
# ... and a simulated sweep's folder is not continued as a rig sweep.
mkdir -p "$dir/ss"
printf '%s\n' 'axes: {mirror.fast.frequency_hz: [205]}' 'base: {seed: 1}' > "$dir/ss/sweep.yaml"
if "$msmcal" sweep --resume "$dir/ss" --rig "$rig" --reference "$dir/ref" > "$dir/ssr.out" 2>&1; then
  echo "FAIL: a simulated sweep continued with --rig"; cat "$dir/ssr.out"; exit 1
fi
cat "$dir/ssr.out"
expect "$dir/ssr.out" "holds a simulated sweep"
test ! -e "$dir/ss/sweep_state.json"
# A stored plan that is not YAML: the report names the file and the line.
mkdir -p "$dir/bad"
printf '%s\n' 'axes: {a: [1, 2]' 'base: {' > "$dir/bad/sweep.yaml"
if "$msmcal" report "$dir/bad" > "$dir/bad.out" 2>&1; then
  echo "FAIL: a broken sweep.yaml reported"; cat "$dir/bad.out"; exit 1
fi
cat "$dir/bad.out"
expect "$dir/bad.out" "$dir/bad/sweep.yaml:"
expect "$dir/bad.out" "YAML syntax error"
if grep -q -F "sweep.yaml:0:" "$dir/bad.out"; then echo "FAIL: line 0"; exit 1; fi
echo PASS
