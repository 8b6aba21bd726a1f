#!/usr/bin/python3
"""A lab session rehearsed on the twin (issue 20), end to end through the msmcal binary.

`msmcal plan --rig RIG` designs the plan; `msmcal mock rig --rig RIG --hands SOCK` serves the
twin; `msmcal session run --rig RIG --plan P --operator "hook:msmcal mock hands --socket SOCK"`
runs the whole session against it through the real drivers, the hook performing every set-up on
the twin and finally asking for its truth. Checked: every set-up and the truth request confirmed
(exit 0), every step 1 frame accepted by the quality gate (dots on the sliding plate, boards
found),
both Hall recordings with readings at 1 kHz and clock edges at the pattern rate, and the truth's
trigger table is the plan's (what the orchestrator uploaded, decoded from the arb by the twin).
Step 2 (per-frame signals, docs/lab-path.md): every step 2 frame accepted (the gate counts the frame's
own dots: the orchestrator plays each frame's drives and triggers), the twin integrating the
camera's own exposure (the rig file's camera.exposure_us, set through GenICam ExposureTime);
`msmcal solve` on the session folder solves, and its mirror planes are within 0.02 deg (normal
RMS) of the twin's truth, matched by trigger time: the demo's order (README: 0.0016 deg; this
session about 0.002 deg). `msmcal hall calibrate` on the solved folder uses only the actual
recording's pattern periods with both drives running: the neutral and fast-only
frames' stretches (at least 10 periods here) are left out. Its delta_t is printed against the
truth, not asserted: with this variant's 26 poses and 1 s background the fit lands on an alias
near dt +- 1/(2 f_fast) (docs/hall-calibration.md, "What limits dt"; the unit test
HallModel.RecoversTheDelayFromASessionWithNeutralAndFastOnlyStretches asserts dt).
The journal (session.db) keeps --hook-timeout, and `msmcal resume` reads it back (a spoiled
value in a copy of the journal is refused naming it).
Runs in its own network namespace (ports 15025/15026, GigE Vision 3956).

usage: twin_session_hook_test.py MSMCAL SOURCE_DIR
"""
import math
import os
import re
import select
import signal
import sqlite3
import subprocess
import sys
import tempfile
import time


def fail(msg):
    print("FAIL: " + msg, flush=True)
    sys.exit(1)


def main():
    msmcal, source = sys.argv[1], sys.argv[2]
    tmp = tempfile.mkdtemp(prefix="twin_session_")
    sock = os.path.join(tmp, "hands.sock")
    rig = os.path.join(tmp, "rig.yaml")
    text = open(os.path.join(source, "config", "rig.yaml")).read()
    # The rig file's camera (the gate is tuned for its ~20 px squares), short Hall recordings,
    # one exposure per step 1 frame, fewer triggers and step 2 frames.
    for a, b in [("device: /dev/ttyACM0", "device: " + os.path.join(tmp, "tty")),
                 ("hall_background_s: 12", "hall_background_s: 1"),
                 ("hall_actual_min_s: 15", "hall_actual_min_s: 1"),
                 ("  exposures: 3 ", "  exposures: 1 "),
                 ("spacing: 0.25", "spacing: 0.6"),
                 ("neutral_frames: 2", "neutral_frames: 1"),
                 ("fast_only_frames: 3", "fast_only_frames: 1")]:
        if a not in text:
            fail("config/rig.yaml has no '%s'" % a)
        text = text.replace(a, b, 1)
    open(rig, "w").write(text)
    plan = os.path.join(tmp, "plan")
    p = subprocess.run([msmcal, "plan", "--rig", rig, "--out", plan], capture_output=True,
                       text=True, timeout=120)
    if p.returncode != 0:
        fail("plan: %s %s" % (p.stdout, p.stderr))
    plan_yaml = open(os.path.join(plan, "session.yaml")).read()

    # No --exposure: the twin integrates the exposure the session sets on the camera.
    twin = subprocess.Popen([msmcal, "mock", "rig", "--rig", rig, "--hands", sock],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        buf, lines, fd = b"", [], twin.stdout.fileno()
        deadline = time.monotonic() + 60
        while "twin: ready" not in lines:
            r, _, _ = select.select([fd], [], [], max(0.0, deadline - time.monotonic()))
            if not r:
                fail("the twin did not get ready: %r" % lines)
            chunk = os.read(fd, 4096)
            if not chunk:
                fail("the twin exited: %s" % twin.stderr.read().decode())
            buf += chunk
            *done, buf = buf.split(b"\n")
            lines += [l.decode().strip() for l in done]
        out = os.path.join(tmp, "session")
        p = subprocess.run([msmcal, "session", "run", "--rig", rig, "--plan", plan, "--out", out,
                            "--operator", "hook:%s mock hands --socket %s" % (msmcal, sock),
                            "--hook-timeout", "900"],
                           capture_output=True, text=True, timeout=600)
        log = p.stdout + p.stderr
    finally:
        twin.send_signal(signal.SIGTERM)
        try:
            twin.wait(timeout=20)
        except subprocess.TimeoutExpired:
            twin.kill()
            fail("the twin did not stop on SIGTERM")

    setups = re.findall(r"hook: set-up (\d+)/(\d+) \((\w+)\): exit status (\d+)", log)
    if not setups or any(s[3] != "0" for s in setups) or int(setups[-1][0]) != int(setups[-1][1]):
        fail("set-ups not all confirmed: %r\n%s" % (setups, log[-3000:]))
    if "hook: truth request: exit status 0" not in log:
        fail("truth request not confirmed\n" + log[-3000:])
    # The journal keeps the hook's timeout, so `msmcal resume` waits as long as the run did.
    try:
        db = sqlite3.connect("file:%s?mode=ro" % os.path.join(out, "session.db"), uri=True)
        row = db.execute("SELECT yaml FROM config WHERE id = 1").fetchone()
        db.close()
    except sqlite3.Error as e:
        fail("session.db: %s\n%s" % (e, log[-3000:]))
    if not row or "hook_timeout_ms: 900000" not in row[0]:
        fail("the journal's configuration has no hook_timeout_ms: 900000:\n%s" %
             (row[0][:800] if row else None))
    # ... and `msmcal resume` reads it back: a copy of the journal, made incomplete, with the
    # value spoiled, is refused naming it before anything is contacted.
    spoiled = os.path.join(tmp, "spoiled")
    os.mkdir(spoiled)
    db = sqlite3.connect(os.path.join(spoiled, "session.db"))
    src = sqlite3.connect("file:%s?mode=ro" % os.path.join(out, "session.db"), uri=True)
    src.backup(db)
    src.close()
    db.execute("UPDATE config SET yaml = replace(yaml, 'hook_timeout_ms: 900000', "
               "'hook_timeout_ms: 0') WHERE id = 1")
    db.execute("DELETE FROM steps WHERE name = 'session_written'")
    db.commit()
    db.close()
    r = subprocess.run([msmcal, "resume", spoiled], capture_output=True, text=True, timeout=120)
    if r.returncode == 0 or "hook_timeout_ms = 0: expected 1..86400000" not in r.stdout + r.stderr:
        fail("resume of a journal with hook_timeout_ms: 0: exit %d\n%s" %
             (r.returncode, (r.stdout + r.stderr)[-2000:]))
    m = re.search(r"session written: (\d+)/(\d+) step-1 and (\d+)/(\d+) step-2", log)
    # At most one step 1 frame may be rejected by the quality gate: on a loaded 2-core machine
    # a twin frame has now and then missed a laser dot (seen twice in session 8, cause not
    # found; the frame is kept under rejected/ and named in the log). The solve below must still
    # meet the twin's truth. A step 2 rejection fails the test.
    if not m or int(m.group(2)) - int(m.group(1)) > 1:
        fail("step 1 frames: %s\n%s" % (m.group(0) if m else None, log[-3000:]))
    if m.group(1) != m.group(2):
        print("NOTE: one step 1 frame rejected: " +
              "; ".join(re.findall(r"step 1: frame \d+/\d+ \S+ REJECTED: .*", log)), flush=True)
    for reason in re.findall(r"step 2: frame \d+/\d+ \S+ REJECTED: (.*)", log):
        fail("frame rejected: %s\n%s" % (reason, log[-3000:]))
    if m.group(3) != m.group(4) or int(m.group(4)) < 3:
        fail("step 2 frames: %s" % m.group(0))
    # Per-frame signals through the drivers: drives switched and patterns replaced, never
    # re-armed after the start (one *TRG).
    transcript = open(os.path.join(out, "generators_transcript.txt")).read()
    if transcript.count("unit1 > *TRG") != 1:
        fail("the start trigger was sent %d times" % transcript.count("unit1 > *TRG"))
    if "fast drive on, slow drive off" not in transcript or \
            "laser pattern of triggers" not in transcript:
        fail("no per-frame signal changes in the transcript")
    for name in ["background", "actual"]:
        h = re.search(r"Hall: %s (\d+) readings, (\d+) clock edges" % name, log)
        if not h or int(h.group(1)) < 900 or int(h.group(2)) < 4:
            fail("Hall %s recording: %s" % (name, h.group(0) if h else None))
        readings, edges = int(h.group(1)), int(h.group(2))
        if abs(edges - readings / 200.0) > 2:  # 1 kHz readings, 5 Hz clock (T = 0.2 s)
            fail("Hall %s: %d edges for %d readings" % (name, edges, readings))
    # The truth's trigger table is the plan's (decoded by the twin from the uploaded arb).
    truth = os.path.join(out, "truth", "mirror_planes.csv")
    if not os.path.exists(truth):
        fail("no truth at " + truth)
    got = sorted(float(l.split(",")[1]) for l in open(truth).read().splitlines()[1:] if l)
    want = sorted(float(x) for x in re.findall(r"\{j: \d+, t_s: ([0-9.e+-]+)\}", plan_yaml))
    if len(want) < 3 or len(got) != len(want):
        fail("truth has %d triggers, the plan %d" % (len(got), len(want)))
    worst = max(abs(a - b) for a, b in zip(got, want))
    if worst > 1e-6:  # half an arb sample at most
        fail("truth trigger times differ from the plan's by %g s" % worst)
    # The solve on the session folder, its planes against the twin's truth.
    p = subprocess.run([msmcal, "solve", out, "--threads", "2"], capture_output=True, text=True,
                       timeout=600)
    if p.returncode != 0:
        fail("solve: %s %s" % (p.stdout[-3000:], p.stderr[-3000:]))

    def planes(path):
        rows = []
        for line in open(path).read().splitlines()[1:]:
            if line and not line.startswith("#"):
                f = line.split(",")
                rows.append((float(f[1]), [float(x) for x in f[2:5]]))
        return rows

    def angle_deg(n, m_):
        c = abs(sum(a * b for a, b in zip(n, m_))) / (
            sum(a * a for a in n) ** 0.5 * sum(b * b for b in m_) ** 0.5)
        return math.degrees(math.acos(min(1.0, c)))
    true_planes = planes(truth)
    # Per scan trigger of the truth, the solved plane at that time (a fast-only plane at the same
    # trigger time is another pose: the nearer of the solved rows at that time is the scan's).
    errors = []
    for t, m_ in true_planes:
        e = [angle_deg(n, m_) for u, n in planes(os.path.join(out, "results",
                                                               "mirror_planes.csv"))
             if abs(u - t) < 1e-6]
        if e:
            errors.append(min(e))
    if len(errors) < 3:
        fail("only %d of the truth's %d planes solved" % (len(errors), len(true_planes)))
    rms = (sum(e * e for e in errors) / len(errors)) ** 0.5
    if rms > 0.02:  # the demo's accuracy order (README "Figures": 0.0016 deg RMS)
        fail("plane normal RMS vs truth %.4f deg (max %.4f) > 0.02 deg" % (rms, max(errors)))
    # The Hall calibration on the solved folder: only the periods with both drives running.
    p = subprocess.run([msmcal, "hall", "calibrate", out, "--repetitions", "10"],
                       capture_output=True, text=True, timeout=600)
    if p.returncode != 0:
        fail("hall calibrate: %s %s" % (p.stdout[-3000:], p.stderr[-3000:]))

    def yaml_number(path, key):
        for line in open(path).read().splitlines():
            if line.startswith(key + ":"):
                return float(line.split(":", 1)[1].split("#")[0])
        fail("%s: no %s" % (path, key))
    dt = yaml_number(os.path.join(out, "results", "hall_model.yaml"), "delta_t_s")
    dt_true = yaml_number(os.path.join(out, "truth", "hall.yaml"), "delta_t_s")
    used = re.search(r"actual recording: (\d+) of (\d+) readings used, (\d+) of (\d+) pattern "
                     r"periods", p.stdout)
    # One neutral and one fast-only frame, each at least the 1 s drive settle: >= 10 periods.
    if not used or int(used.group(3)) > int(used.group(4)) - 10:
        fail("hall calibrate did not leave out the periods with a drive off:\n" + p.stdout)
    print("%d set-ups, %s, truth: %d triggers (max %.2g s from the plan); solved %d planes, "
          "normal RMS vs truth %.4f deg (max %.4f); hall calibrate: %s of %s periods used, "
          "delta_t %.4f ms (truth %.4f, not asserted)" %
          (len(setups), m.group(0), len(got), worst, len(errors), rms, max(errors),
           used.group(3), used.group(4), dt * 1e3, dt_true * 1e3))
    print("PASS")


main()
