#!/usr/bin/env bash
# `msmcal session run` (the guided lab session) before any instrument answers: a plan folder with
# a bad file is refused naming the file; with no instruments on the rig the rig check refuses to
# start with the list of what is wrong, the refusal is journalled in the new session folder, and
# generator outputs were never switched on. Runs in its own network namespace (nothing listens).
set -euo pipefail
msmcal="$1"
src="$2"
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
cat > "$dir/tiny.yaml" <<'YAML'
seed: 3
step1: {poses: 4}
step2: {neutral_frames: 1, fast_only_frames: 2}
triggers: {max_triggers: 18}
YAML
"$msmcal" simulate "$dir/sim" --config "$dir/tiny.yaml" --no-images > /dev/null
mkdir -p "$dir/plan"
cp "$dir/sim/session.yaml" "$dir/sim/camera.yaml" "$dir/plan/"

# A plan without camera.yaml: the error names the file.
mkdir -p "$dir/badplan"
cp "$dir/sim/session.yaml" "$dir/badplan/"
if "$msmcal" session run --rig "$src/config/rig.yaml" --camera 127.0.0.9 --plan "$dir/badplan" \
    --out "$dir/s0" < /dev/null > "$dir/err0" 2>&1; then
  echo "expected a failure for a plan without camera.yaml"; exit 1
fi
grep -q "badplan/camera.yaml" "$dir/err0" || { cat "$dir/err0"; exit 1; }

# No instruments: refused with one line per problem, journalled.
if "$msmcal" session run --rig "$src/config/rig.yaml" --camera 127.0.0.9 --plan "$dir/plan" \
    --mcu "$dir/no-such-tty" --out "$dir/s1" < /dev/null > "$dir/err1" 2>&1; then
  echo "expected the rig check to refuse"; exit 1
fi
cat "$dir/err1"
grep -q "rig check failed, not starting" "$dir/err1"
grep -q "generator 1 (127.0.0.1:15025)" "$dir/err1"
grep -q "generator 2 (127.0.0.1:15026)" "$dir/err1"
grep -q "camera 127.0.0.9" "$dir/err1"
grep -q "no-such-tty" "$dir/err1"
/usr/bin/python3 - "$dir/s1/session.db" <<'PY'
import sqlite3, sys
db = sqlite3.connect(sys.argv[1])
kind = dict(db.execute("SELECT key, value FROM meta"))["run.kind"]
assert kind == "lab", kind
problems = [m for (m,) in db.execute("SELECT message FROM events WHERE kind = 'error'")]
assert any("rig check PROBLEM: generator 1" in m for m in problems), problems
assert any("refused to start" in m for m in problems), problems
steps = dict(db.execute("SELECT name, state FROM steps"))
assert steps["step1"] == "pending" and steps["rig_check"] == "running", steps
PY
# The journal keeps what `msmcal resume` needs: it retries the rig check (and refuses again).
if "$msmcal" resume "$dir/s1" < /dev/null > "$dir/err2" 2>&1; then
  echo "expected the resumed rig check to refuse"; exit 1
fi
grep -q "lab session" "$dir/err2"
grep -q "rig check failed, not starting" "$dir/err2"
# The catalogue lists the refused session (no results yet) in aligned columns.
"$msmcal" sessions list --root "$dir" > "$dir/list"
cat "$dir/list"
/usr/bin/python3 - "$dir/list" <<'PY'
import sys
lines = open(sys.argv[1]).read().splitlines()
header, rows = lines[0], [l for l in lines[1:-1]]
assert lines[-1].startswith("1 session(s) under"), lines[-1]
assert len(rows) == 1 and rows[0].startswith("s1 "), rows
col = header.index("RESULT RMS")
assert rows[0][col:].strip() == "-", rows[0]   # not solved
assert rows[0][header.index("FRAMES"):].split()[0] == "0", rows[0]
PY
echo "session run / resume refusals: ok"
