#!/usr/bin/python3
"""Acceptance test of `msmcal sweep` (issue 9): a sweep killed with SIGKILL mid-point resumes and
finishes with nothing lost.

Usage: sweep_cli_test.py MSMCAL_BINARY  (run in its own network namespace: the demo rig serves
GigE Vision on 127.0.0.1:3956).

Starts a 2-point tiny sweep, reads its progress lines until point 2 reports its first accepted
frame, SIGKILLs the whole process group, then re-runs the same command and checks: exit 0;
point 1 was not re-acquired (its images, session.yaml and journal frame rows unchanged); the
frames point 2 recorded before the kill are kept (same bytes and mtimes, same journal rows, the
resumed run says so); summary.csv lists both points done with solver and Hall figures. No sleeps:
the test synchronises on the child's output lines.
"""
import csv
import hashlib
import json
import os
import shutil
import signal
import sqlite3
import subprocess
import sys
import tempfile

PLAN = """\
note: sweep CLI acceptance test (tiny simulator)
base:
  seed: 3
  step1:
    poses: 4
    exposures: 1
  step2:
    neutral_frames: 1
    fast_only_frames: 2
  triggers:
    max_triggers: 30
    min_separation_px: 13
  camera:  # half resolution, same field of view: a quarter of the pixels
    width: 1224
    height: 1024
    fx: 1000
    fy: 1000
    cx: 611.5
    cy: 511.5
  hall:
    background_duration_s: 2
    actual_duration_s: 2
axes:
  hall.noise_uT: [1.5, 2.0]
"""


def fail(msg):
    print("FAIL: " + msg, flush=True)
    sys.exit(1)


def files_state(folder):
    """Relative path -> (sha256, mtime_ns) of every image, session.yaml and result file."""
    out = {}
    for root, _, names in os.walk(folder):
        for n in names:
            p = os.path.join(root, n)
            rel = os.path.relpath(p, folder)
            if not (n.endswith(".png") or rel == "session.yaml" or rel.startswith("results")):
                continue
            with open(p, "rb") as f:
                out[rel] = (hashlib.sha256(f.read()).hexdigest(), os.stat(p).st_mtime_ns)
    return out


def frame_rows(folder):
    db = os.path.join(folder, "session.db")
    if not os.path.exists(db):
        return []
    # A copy: reading must not touch the sweep's own files.
    tmp = tempfile.mkdtemp()
    for suffix in ("", "-wal", "-shm"):
        if os.path.exists(db + suffix):
            shutil.copy(db + suffix, os.path.join(tmp, "session.db" + suffix))
    con = sqlite3.connect(os.path.join(tmp, "session.db"))
    rows = con.execute("SELECT id, step, file, accepted FROM frames ORDER BY id").fetchall()
    con.close()
    shutil.rmtree(tmp)
    return rows


def main():
    exe = os.path.abspath(sys.argv[1])
    work = tempfile.mkdtemp(prefix="sweep_cli_")
    plan = os.path.join(work, "plan.yaml")
    with open(plan, "w") as f:
        f.write(PLAN)
    out = os.path.join(work, "sweep")
    cmd = [exe, "sweep", plan, "--out", out]

    listing = subprocess.run([exe, "sweep", plan, "--out", out, "--list"], capture_output=True,
                             text=True, check=True).stdout
    names = [l.split()[0] for l in listing.splitlines() if l.startswith("  p")]
    if len(names) != 2:
        fail("--list: expected 2 points:\n" + listing)
    p1, p2 = (os.path.join(out, n) for n in names)

    # Run 1: until point 2's first accepted frame, then SIGKILL.
    child = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                             start_new_session=True)
    seen = []
    killed = False
    for line in child.stdout:
        seen.append(line.rstrip("\n"))
        print("run1| " + seen[-1], flush=True)
        if line.startswith("sweep 2/2") and " frame " in line and " accepted |" in line:
            os.killpg(child.pid, signal.SIGKILL)
            killed = True
            break
    child.stdout.close()
    child.wait()
    if not killed:
        fail("point 2 never reported an accepted frame (exit %s)" % child.returncode)
    if not any(l.startswith("sweep 1/2") and " done " in l for l in seen):
        fail("point 1 was not reported done before point 2 started")

    p1_files, p1_rows = files_state(p1), frame_rows(p1)
    p2_files, p2_rows = files_state(p2), frame_rows(p2)
    if not p1_rows or not any(k.startswith("results") for k in p1_files):
        fail("point 1 has no journal frames or no results")
    p2_images = {k: v for k, v in p2_files.items() if k.startswith("step")}
    if not p2_rows or not p2_images:
        fail("point 2 recorded no frame before the kill")
    if os.path.exists(os.path.join(p2, "session.yaml")):
        fail("point 2 was complete before the kill: not a mid-point kill")

    # Run 2: the same command continues the sweep.
    res = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    for l in res.stdout.splitlines():
        print("run2| " + l, flush=True)
    if res.returncode != 0:
        fail("resumed sweep exited with %d" % res.returncode)
    lines = res.stdout.splitlines()
    if not any(l.startswith("sweep 1/2") and "skipped" in l for l in lines):
        fail("point 1 was not skipped by the resumed run")
    if any(l.startswith("sweep 1/2") and " frame " in l for l in lines):
        fail("point 1 took frames again")
    if not any(l.startswith("sweep 2/2") and "resume ->" in l for l in lines):
        fail("point 2 was not resumed from its journal")
    if not any(l.startswith("sweep 2/2") and "kept from before the resume" in l for l in lines):
        fail("the resumed run does not report point 2's recorded frames as kept")

    # Nothing lost, nothing re-acquired.
    if files_state(p1) != p1_files:
        fail("point 1's images/results changed")
    if frame_rows(p1) != p1_rows:
        fail("point 1's journal frame rows changed")
    after = files_state(p2)
    for rel, state in p2_images.items():
        if after.get(rel) != state:
            fail("point 2's frame %s, recorded before the kill, was changed or lost" % rel)
    rows_after = frame_rows(p2)
    if rows_after[:len(p2_rows)] != p2_rows:
        fail("point 2's journal frame rows recorded before the kill changed")
    with open(os.path.join(p2, "session_log.txt")) as f:
        if "RESUMED" not in f.read():
            fail("point 2's session log does not record the resume")

    with open(os.path.join(out, "summary.csv")) as f:
        rows = list(csv.DictReader(f))
    if [r["point"] for r in rows] != names:
        fail("summary.csv points: %s" % [r["point"] for r in rows])
    for r in rows:
        if not r["status"].startswith("done"):
            fail("summary: %s status %s (%s)" % (r["point"], r["status"], r["reason"]))
        if not r["validation_rms_deg"] or not r["hall_model"] or int(r["frames_accepted"]) < 1:
            fail("summary: %s lacks figures: %s" % (r["point"], r))
    if not any("2 points: 2 done, 0 failed" in l for l in lines):
        fail("the printed summary does not count 2 done points")
    with open(os.path.join(out, "sweep_state.json")) as f:
        state = json.load(f)["points"]
    if state[names[0]]["attempts"] != 1 or state[names[1]]["attempts"] != 2:
        fail("sweep_state.json attempts: %s" % state)

    # --resume on a finished sweep: everything skipped, nothing run.
    res = subprocess.run([exe, "sweep", "--resume", out], stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, text=True)
    skipped = [l for l in res.stdout.splitlines() if l.startswith("sweep ") and " skipped " in l]
    if res.returncode != 0 or len(skipped) != 2:
        fail("--resume of a finished sweep:\n" + res.stdout)
    if files_state(p2) != after:
        fail("--resume of a finished sweep changed point 2")
    # A different plan on the same folder is refused, naming the difference.
    other = os.path.join(work, "other.yaml")
    with open(other, "w") as f:
        f.write(PLAN.replace("[1.5, 2.0]", "[1.5, 2.5]"))
    res = subprocess.run([exe, "sweep", other, "--out", out], stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, text=True)
    if res.returncode == 0 or "holds a different sweep" not in res.stdout:
        fail("a changed plan was not refused:\n" + res.stdout)
    shutil.rmtree(work)
    print("PASS", flush=True)


if __name__ == "__main__":
    main()
