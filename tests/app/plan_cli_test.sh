#!/usr/bin/env bash
# The lab path's first steps through the msmcal binary: `msmcal plan` from config/rig.yaml writes a
# plan the shared interchange validator finds no key or structure problem in (only the images and
# Hall files a plan does not have yet), prints its summary; `session run --dry-run` prints the
# summary and creates nothing (no instrument is contacted: nothing listens in this test's network
# namespace); a plan beyond the rig's limits and a rig beyond its own are refused naming the
# field and the limit.
set -euo pipefail
msmcal="$1"
src="$2"
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT

"$msmcal" plan --rig "$src/config/rig.yaml" --out "$dir/plan" > "$dir/plan.out"
cat "$dir/plan.out"
grep -q "^frames: 48 step 1, 30 step 2 (73 triggers)$" "$dir/plan.out"
grep -q "^prompts: 19 set-ups" "$dir/plan.out"
grep -q "^expected duration: about " "$dir/plan.out"
grep -q "^disk needed: about " "$dir/plan.out"
test -f "$dir/plan/session.yaml" && test -f "$dir/plan/camera.yaml"
# A second plan into the same folder needs --force.
if "$msmcal" plan --rig "$src/config/rig.yaml" --out "$dir/plan" > "$dir/err" 2>&1; then
  echo "expected a refusal to overwrite the plan"; exit 1
fi
grep -q "holds a plan already (--force replaces it)" "$dir/err"
"$msmcal" plan --rig "$src/config/rig.yaml" --out "$dir/plan" --force --setups "$dir/setups.jsonl" \
  > /dev/null
# --setups: one JSON set-up per line, as many as the prompts announced, blocks 1..19 in order.
/usr/bin/python3 - "$dir/setups.jsonl" <<'PY'
import json, sys
lines = open(sys.argv[1]).read().splitlines()
assert len(lines) == 19, len(lines)
for k, line in enumerate(lines):
    s = json.loads(line)
    assert s["msmcal_setup"] == 1 and s["kind"] == "setup", s
    assert s["block"] == k + 1 and s["of"] == 19, s
    assert s["for"]["step"] in ("step1", "hall_background", "hall_actual", "step2"), s
    assert s["camera"] in ("C1", "C2") and s["drive"] in ("off", "fast_only", "scan"), s
    assert s["text"].startswith("\n=== [%d/19] " % (k + 1)), s["text"]
PY

# The shared validator: every problem it reports is a file a plan does not have yet.
if [ -x /work/shared/tools/validate-interchange ]; then
  /usr/bin/python3 /work/shared/tools/validate-interchange "$dir/plan" > "$dir/validate" || true
  if grep -v -E "^missing (step[12]/[0-9]{4}\.png|hall/[a-z_]+\.csv)$|^FAIL: [0-9]+ problems$" \
      "$dir/validate"; then
    echo "validate-interchange found more than missing images and Hall files"; exit 1
  fi
fi

# Rehearsal: the summary, DIR not created.
"$msmcal" session run --rig "$src/config/rig.yaml" --plan "$dir/plan" --out "$dir/new/s1" \
    --dry-run > "$dir/dry.out"
cat "$dir/dry.out"
grep -q "^prompts: 19 set-ups" "$dir/dry.out"
grep -q "^free disk at $dir: " "$dir/dry.out"
grep -q "^dry run: the plan fits the rig's limits$" "$dir/dry.out"
test ! -e "$dir/new"

# A plan beyond the mirror's limits (edited by hand): refused, naming the field and the limit.
mkdir "$dir/bad"
cp "$dir/plan/camera.yaml" "$dir/bad/"
sed 's/fast: {frequency_hz: 205,/fast: {frequency_hz: 260,/' "$dir/plan/session.yaml" \
  > "$dir/bad/session.yaml"
if "$msmcal" session run --rig "$src/config/rig.yaml" --plan "$dir/bad" --out "$dir/new/s2" \
    --dry-run > "$dir/err" 2>&1; then
  echo "expected the dry run to refuse a drive outside the window"; exit 1
fi
cat "$dir/err"
grep -q "plan drive: generators.unit1.ch1 (fast_coil): frequency_hz = 260 outside the window \[195, 215\] Hz" "$dir/err"
test ! -e "$dir/new"

# A rig whose drive is outside the fast coil's window: `msmcal plan` refuses, naming the channel's
# field, the value and the window, and writes nothing.
sed 's/fast: {frequency_hz: 205,/fast: {frequency_hz: 230,/' "$src/config/rig.yaml" > "$dir/win.yaml"
if "$msmcal" plan --rig "$dir/win.yaml" --out "$dir/plan3" > "$dir/err" 2>&1; then
  echo "expected plan to refuse a drive outside the window"; exit 1
fi
cat "$dir/err"
grep -q "win.yaml:[0-9]*: generators.unit1.ch1 (fast_coil): frequency_hz = 230 outside the window \[195, 215\] Hz" "$dir/err"
test ! -e "$dir/plan3"

# A rig whose trigger design is over the duty limit: `msmcal plan` refuses, writes nothing.
sed 's/pulse_width_s: 1.0e-6/pulse_width_s: 1.0e-4/' "$src/config/rig.yaml" > "$dir/duty.yaml"
if "$msmcal" plan --rig "$dir/duty.yaml" --out "$dir/plan2" > "$dir/err" 2>&1; then
  echo "expected plan to refuse the duty"; exit 1
fi
cat "$dir/err"
grep -q "duty.yaml:[0-9]*: generators.signals: trigger design: duty = .* exceeds trigger.max_duty = 0.01" "$dir/err"
test ! -e "$dir/plan2"

# An operator spec that is neither console nor hook:CMD.
if "$msmcal" session run --rig "$src/config/rig.yaml" --plan "$dir/plan" --out "$dir/new/s3" \
    --operator robot --dry-run > "$dir/err" 2>&1; then
  echo "expected a refusal of --operator robot"; exit 1
fi
grep -q "\-\-operator = 'robot': must be console or hook:CMD" "$dir/err"

# --frame-rate follows the rig file's camera rule before anything (the dry run included): in
# (0, 1000] Hz, not NaN, and a period not shorter than camera.exposure_us (220 000 us here);
# a valid one is what the rehearsal's duration uses. --hook-timeout is bounded as the sweep's.
refuse_run() {  # expected message, options...
  local expected="$1"
  shift
  if "$msmcal" session run --rig "$src/config/rig.yaml" --plan "$dir/plan" --out "$dir/new/s4" \
      --dry-run "$@" > "$dir/err" 2>&1; then
    echo "expected a refusal of $*"; cat "$dir/err"; exit 1
  fi
  cat "$dir/err"
  grep -q -F -- "$expected" "$dir/err" || { echo "no '$expected' for $*"; exit 1; }
  test ! -e "$dir/new"
}
refuse_run "--frame-rate = 5000: must be in (0, 1000] Hz" --frame-rate 5000
refuse_run "--frame-rate: 'nan': expected a finite number" --frame-rate nan
refuse_run "--frame-rate = 0: must be in (0, 1000] Hz" --frame-rate 0
refuse_run "--frame-rate = 10: its frame period 1e6 / 10 = 100000 us is shorter than camera.exposure_us = 220000 us" --frame-rate 10
refuse_run "--hook-timeout = 100000: must be in (0, 86400] s" --hook-timeout 100000
"$msmcal" session run --rig "$src/config/rig.yaml" --plan "$dir/plan" --out "$dir/new/s5" \
    --dry-run --frame-rate 2 > "$dir/dry2.out"
grep -q "^dry run: the plan fits the rig's limits$" "$dir/dry2.out"
if cmp -s "$dir/dry.out" "$dir/dry2.out"; then
  echo "--frame-rate 2 did not reach the rehearsal's summary"; exit 1
fi
test ! -e "$dir/new"
echo "plan / dry run: ok"
