#!/usr/bin/python3
"""The fault campaign of issue 17 (docs/fault-campaign.md).

Runs every fault against the mocks, one small demo session per fault, and prints one table row per
fault: outputs off (queried from the mock generators after the session), the error shown, data lost
(frames and Hall readings on disk against the journal) and the result of `msmcal resume`. Ends with
`N passed, M failed`; the exit status is 1 when any failed.

Each fault runs in its own user, network and mount namespaces (`unshare -rnm`): the GigE Vision
camera's fixed port and its broadcasts stay inside, and the disk-full faults mount a small tmpfs
that nobody else sees. The row runs this script again inside the namespaces (`--run-row`), which
prints the row as one JSON line.

The mock generators are a separate process (`msmcal mock generators --second-connection queue`,
one SCPI connection served at a time, as the strictest 33500), so their outputs can be queried after
msmcal is gone; the demo reaches them by `--generator-ports`. Camera and Hall MCU faults are the
demo rig's own mocks' (`msmcal demo --mock-fault`). Points in a session are waited for on the
session's progress lines, never by sleeping; that the fault or signal landed where it was meant to
is then checked in the journal.
"""

import argparse
import dataclasses
import errno
import fnmatch
import hashlib
import json
import os
import re
import shutil
import signal
import sqlite3
import subprocess
import sys
import tempfile
import time

from msmcal_harness import Lines, scpi, wait_pid  # scripts/msmcal_harness.py

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
PORTS = (15025, 15026)  # config/rig.yaml's mock units (each row has its own network namespace)

# The session of every row: 10 step-1 and 13 step-2 frames at 2448 x 2048, 30 triggers, 2 s Hall
# recordings; about 25 s of acquisition and 15 s of solve + Hall calibration here, and it solves.
SIM_YAML = """\
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
"""

SESSION_DEADLINE_S = 300  # one demo session or one resume, on a busy 2-core machine
POINT_DEADLINE_S = 180    # reaching the point of a signal or a disk-full fault
WATCHDOG_DEADLINE_S = 5   # the watchdog's 1.5 s window, with margin

# Progress lines that mark the points of a session (app/cmd_demo.cc prints the session log).
POINTS = {
    # The rig check is held open by a 1.5 s reply delay of unit 2's *IDN? (below the driver's 3 s
    # timeout); the signal goes as soon as the session announces itself.
    "rig check": r"\] session .*: \d+ step-1 frames",
    "step 1": r"\] step 1: frame 3/",
    # The background recording is held open by a 1.5 s stall of its MCU (below the 2 s timeout).
    "background": r"\] Hall: background recording on",
    "step 2": r"\] step 2: frame 3/",
}
# The journal step that must be running when the signal lands (checked afterwards).
POINT_STEP = {"rig check": "rig_check", "step 1": "step1", "background": "hall_background",
              "step 2": "step2"}
POINT_HOLD = {
    "rig check": {"gen": ["unit2:delay,match=*IDN?,ms=1500"]},
    "background": {"mock": ["mcu-background:stall@1000:1500"]},
}


@dataclasses.dataclass
class Fault:
    name: str
    what: str                      # one line for the table and docs/fault-campaign.md
    expect: str                    # "error": the session stops with an error; "complete"; "signal"
    gen: list = dataclasses.field(default_factory=list)   # msmcal mock generators --fault
    mock: list = dataclasses.field(default_factory=list)  # msmcal demo --mock-fault
    error: str = ""                # regex the shown error (or warning) must match
    disk: str = ""                 # "images" / "hall": fill the tmpfs at that point
    signal: str = ""               # "INT", ..., "KILL"
    point: str = ""                # key of POINTS
    lost_readings: int = 0         # readings the fault destroys on the wire (reported, expected)


def faults():
    f = [
        Fault("scpi-drop-rig-check", "unit 2 closes the connection at its *IDN? (rig check)",
              "error", gen=["unit2:drop,match=*IDN?"], error=r"generator 2 .*15026"),
        Fault("scpi-drop-apply", "unit 1 closes the connection at OUTP2 ON (ch1 already on)",
              "error", gen=["unit1:drop,match=OUTP2 ON"], error=r"127\.0\.0\.1:15025"),
        # The safe state's message is "OUTP1 OFF;:OUTP2 OFF": a bare "OUTP1 OFF" is also the
        # drive switches between set-ups (per-frame signals).
        Fault("scpi-drop-safe-state",
              "unit 1 closes the connection at the final OUTP1 OFF;:OUTP2 OFF",
              "complete", gen=["unit1:drop,match=OUTP1 OFF;"], error=r"safe state"),
        # Per-frame signals: step 2 uploads each frame's laser pattern to unit 2 (the 1st upload
        # is the apply's, the 2nd and 3rd step 2's first two frames).
        Fault("scpi-drop-step2", "unit 2 closes the connection at a step 2 frame's laser pattern "
              "upload (its 4th DATA:ARB:DAC)", "error",
              gen=["unit2:drop,match=DATA:ARB:DAC,after=3"], error=r"127\.0\.0\.1:15026"),
        Fault("scpi-delay-short", "unit 1 answers *OPC? after *TRG 1 s late (below the timeout)",
              "complete", gen=["unit1:delay,match=*OPC?,after=4,ms=1000"]),
        Fault("scpi-delay-timeout", "unit 1 answers *OPC? after *TRG 5 s late (over the 3 s timeout)",
              "error", gen=["unit1:delay,match=*OPC?,after=4,ms=5000"],
              error=r"127\.0\.0\.1:15025: deadline expired"),
        Fault("scpi-garbage", "unit 1 answers *OPC? after *TRG with non-SCPI bytes",
              "error", gen=["unit1:garbage,match=*OPC?,after=4"],
              error=r"127\.0\.0\.1:15025: .*reply"),
        Fault("scpi-frozen", "unit 1 stops serving its connection at *TRG (outputs on)",
              "error", gen=["unit1:freeze,match=*TRG"],
              error=r"127\.0\.0\.1:15025: deadline expired"),
        Fault("camera-loss", "the camera stops serving after 60 frames (step 1)",
              "error", mock=["camera:lost@60"], error=r"camera"),
        Fault("mcu-corrupt-bit", "one bit flipped in reading 500 of the actual recording",
              "complete", mock=["mcu-actual:flip@500"], error=r"1 lost", lost_readings=1),
        Fault("mcu-drop-byte", "one byte dropped from reading 700 of the actual recording",
              "complete", mock=["mcu-actual:drop@700"], error=r"1 lost", lost_readings=1),
        Fault("mcu-reset", "the MCU reboots in the middle of the actual recording",
              "error", mock=["mcu-actual:reset@800"], error=r"MCU reset during the recording"),
        Fault("mcu-stall", "the MCU goes silent in the middle of the actual recording",
              "error", mock=["mcu-actual:stall@800"], error=r"(?i)stall|silent|no data"),
        Fault("disk-full-images", "the image path's disk fills in step 1 (32 KiB left)",
              "error", disk="images", point="step 1", error=r"No space left on device"),
        Fault("disk-full-hall", "the Hall path's disk fills in the background recording (8 KiB left)",
              "error", disk="hall", point="background", error=r"No space left on device",
              mock=["mcu-background:stall@200:1500"]),
    ]
    for sig in ("INT", "TERM", "HUP", "QUIT", "PIPE", "KILL"):
        for point in POINTS:
            hold = POINT_HOLD.get(point, {})
            # SIGPIPE is ignored (SafeStateGuard while the outputs may be on, so that a closed
            # socket gives EPIPE, not death; and before it, msmcal's start-up): a stray one
            # changes nothing.
            expect = "complete" if sig == "PIPE" else "signal"
            f.append(Fault(f"sig{sig}-{point.replace(' ', '')}", f"SIG{sig} in {point}", expect,
                           gen=list(hold.get("gen", [])), mock=list(hold.get("mock", [])),
                           signal=sig, point=point))
    return f


# A CI-sized subset (tests/app/fault_campaign_ci_test.sh).
CI_SUBSET = ["scpi-drop-apply", "mcu-stall", "disk-full-images", "sigKILL-step1"]


# ---------------------------------------------------------------------------------------------
# Inside the namespaces: one row.

CHILDREN = []  # processes a row started (ended by the row runner if it fails)


class Session:
    """A running msmcal process (its own process group) whose output lines go to `log_path` and
    can be waited for (msmcal_harness.Lines)."""

    def __init__(self, argv, log_path):
        self.log = open(log_path, "w")
        self.proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     stdin=subprocess.DEVNULL, text=True, errors="replace",
                                     start_new_session=True)
        CHILDREN.append(self.proc)
        self.lines = Lines(self.proc, log=self.log)

    def wait_line(self, pattern, deadline_s):
        return self.lines.wait_for(pattern, deadline_s) is not None

    def wait(self, deadline_s):
        try:
            self.proc.wait(timeout=deadline_s)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
            self.lines.append("(campaign: killed after %d s)" % deadline_s)
        self.lines.reader.join(5)
        self.log.close()
        return self.proc.returncode

    def text(self):
        return self.lines.text()


def fill_disk(path, leave_bytes):
    """Leaves about `leave_bytes` free on the file system of `path` (the session writes while
    this runs: a fallocate the space is gone for is tried again, smaller)."""
    with open(os.path.join(path, ".campaign-filler"), "wb") as f:
        for _ in range(100):
            st = os.statvfs(path)
            free = st.f_bavail * st.f_frsize
            if free <= leave_bytes:
                return
            try:
                os.posix_fallocate(f.fileno(), 0, os.fstat(f.fileno()).st_size + free - leave_bytes)
                return
            except OSError as e:
                if e.errno != errno.ENOSPC:
                    raise
                leave_bytes += 64 * 1024


def journal(dir_):
    db_path = os.path.join(dir_, "session.db")
    if not os.path.exists(db_path):
        return None
    db = sqlite3.connect("file:%s?mode=ro" % db_path, uri=True)
    try:
        j = {
            "steps": dict(db.execute("SELECT name, state FROM steps")),
            "frames": [r[0] for r in db.execute("SELECT file FROM frames")],
            "readings": dict(db.execute(
                "SELECT recording, COUNT(*) FROM hall_readings GROUP BY recording")),
            "errors": [r[0] for r in db.execute(
                "SELECT message FROM events WHERE kind = 'error' ORDER BY id")],
            "warnings": [r[0] for r in db.execute(
                "SELECT message FROM events WHERE kind = 'warning' ORDER BY id")],
        }
    finally:
        db.close()
    return j


def step_state(dir_, step):
    try:
        j = journal(dir_)
    except sqlite3.Error:
        return None  # being created
    return j["steps"].get(step) if j else None


def wait_step_running(dir_, step, session, deadline_s=10.0):
    """Watches the journal until `step` is running (the progress line of a point can come just
    before the journal's step state); polled every 20 ms, bounded."""
    end = time.monotonic() + deadline_s
    while time.monotonic() < end and session.proc.poll() is None:
        if step_state(dir_, step) == "running":
            return True
        time.sleep(0.02)
    return False


def csv_rows(path):
    with open(path, "rb") as f:
        lines = [l for l in f.read().split(b"\n") if l.strip() and not l.startswith(b"#")]
    return max(0, len(lines) - 1)  # the header


def data_lost(dir_, j):
    """Frames and readings the journal records that are not on disk as recorded."""
    lost_frames = [f for f in j["frames"] if not os.path.exists(os.path.join(dir_, f))]
    lost_readings = 0
    for rec, n in j["readings"].items():
        csv = os.path.join(dir_, "hall", rec + ".csv")
        on_disk = csv_rows(csv) if os.path.exists(csv) else 0
        lost_readings += max(0, n - on_disk)
    return lost_frames, lost_readings


def hashes(dir_, files):
    out = {}
    for f in files:
        p = os.path.join(dir_, f)
        if os.path.exists(p):
            with open(p, "rb") as fh:
                out[f] = hashlib.sha256(fh.read()).hexdigest()
    return out


def shown_error(text, rc):
    """The line a person at the terminal reads as the reason (the last error, else warning)."""
    lines = text.splitlines()
    # The acquisition's part: the finish steps after it (solve, Hall calibration) print tables.
    for i, l in enumerate(lines):
        if l.startswith("$ msmcal ") or "acquisition done:" in l:
            lines = lines[:i]
            break
    for pat in (r"\[error\]", r"(?i)error|FAILED|PROBLEM", r"(?i)warning"):
        hits = [i for i, l in enumerate(lines) if re.search(pat, l)]
        if hits:
            i = hits[-1]
            shown = re.sub(r"^\[[^\]]*\] (\[[a-z]+\] )?", "", lines[i]).strip()
            if shown.endswith(":") and i + 1 < len(lines):  # a list follows: its first item
                shown += " " + lines[i + 1].strip()
            return shown
    return ""


def finish_error(text):
    """The error of a finish step (solve, Hall calibration, Hall prediction): the first
    `[error]` line after a `$ msmcal ...` line, with the command it came from."""
    command = ""
    for l in text.splitlines():
        if l.startswith("$ msmcal "):
            words = l.split(" ")[2:4]  # "solve DIR", "hall calibrate", "hall predict"
            command = " ".join(words if words[:1] == ["hall"] else words[:1])
        elif re.search(r"\[error\]|FAILED", l):
            shown = re.sub(r"^\[[^\]]*\] (\[[a-z]+\] )?", "", l).strip()
            return "%s: %s" % (command, shown) if command else shown
    return ""


def run_row(fault, msmcal, work):
    subprocess.run(["ip", "link", "set", "lo", "up"], check=True)
    import ctypes
    ctypes.CDLL(None, use_errno=True).prctl(36, 1, 0, 0, 0)  # PR_SET_CHILD_SUBREAPER
    os.makedirs(work, exist_ok=True)
    row = {"name": fault.name, "what": fault.what, "ok": True, "why": []}

    def check(cond, why):
        if not cond:
            row["ok"] = False
            row["why"].append(why)
        return cond

    sim = os.path.join(work, "sim.yaml")
    with open(sim, "w") as f:
        f.write(SIM_YAML)
    out = os.path.join(work, "session")
    os.makedirs(out)
    if fault.disk:
        subprocess.run(["mount", "-t", "tmpfs", "-o", "size=96m", "tmpfs", out], check=True)

    gen_log = open(os.path.join(work, "generators.log"), "w")
    gen_argv = [msmcal, "mock", "generators", "--rig", os.path.join(ROOT, "config", "rig.yaml"),
                "--second-connection", "queue"]
    for g in fault.gen:
        gen_argv += ["--fault", g]
    gens = subprocess.Popen(gen_argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    CHILDREN.append(gens)
    listening = 0
    for line in gens.stdout:
        gen_log.write(line)
        listening += line.startswith("listening on")
        if listening == 2:
            break
    check(listening == 2, "mock generators did not start")

    argv = [msmcal, "demo", "--out", out, "--config", sim,
            "--generator-ports", "%d,%d" % PORTS]
    for m in fault.mock:
        argv += ["--mock-fault", m]
    s = Session(argv, os.path.join(work, "demo.log"))
    landed = True
    if fault.point:
        landed = s.wait_line(POINTS[fault.point], POINT_DEADLINE_S)
        check(landed, "the session never reached " + fault.point)
    if landed and fault.point:
        landed = wait_step_running(out, POINT_STEP[fault.point], s)
        check(landed, "the journal never showed step %s running" % POINT_STEP[fault.point])
    if landed and fault.disk:
        fill_disk(out, 32 * 1024 if fault.disk == "images" else 8 * 1024)
    if landed and fault.signal:
        os.kill(s.proc.pid, getattr(signal, "SIG" + fault.signal))
    if landed and fault.point:
        # Where it landed: the journal's step of the point must be running now.
        state = step_state(out, POINT_STEP[fault.point])
        check(state == "running", "%s: the fault landed with step %s %s (expected running)" %
              (fault.point, POINT_STEP[fault.point], state))
    rc = s.wait(SESSION_DEADLINE_S)
    text = s.text()
    j = journal(out)
    row["exit"] = ("signal %s" % signal.Signals(-rc).name) if rc < 0 else "exit %d" % rc

    # The watchdog (our child now if msmcal died) must be done before the units are asked.
    m = re.search(r"watchdog armed \(pid (\d+)\)", text)
    watchdog_status = None
    if m:
        watchdog_status = wait_pid(int(m.group(1)), WATCHDOG_DEADLINE_S)
    # Outputs, queried from the mock units.
    outputs = []
    for port in PORTS:
        try:
            outputs.append(scpi(port, "OUTP1?;:OUTP2?", timeout_s=4.0))
        except OSError as e:
            outputs.append("no answer (%s)" % e)
    off = all(o == "0;0" for o in outputs)
    row["outputs"] = "off" if off else "ON/unknown: " + " ".join(outputs)
    check(off, "outputs not off: %s" % outputs)

    # The error shown.
    log_text = ""
    if os.path.exists(os.path.join(out, "session_log.txt")):
        with open(os.path.join(out, "session_log.txt"), errors="replace") as f:
            log_text = f.read()
    if fault.signal == "KILL":
        wd = [l for l in log_text.splitlines() if l.startswith("[watchdog")]
        shown = wd[-1] if wd else ""
        if fault.point == "rig check":
            check(rc == -signal.SIGKILL, "not killed")
            shown = shown or "killed before the watchdog was armed (outputs never on)"
        else:
            check("outputs off, confirmed" in shown, "no watchdog confirmation in session_log.txt")
            check(watchdog_status is not None and os.WIFEXITED(watchdog_status)
                  and os.WEXITSTATUS(watchdog_status) == 10,
                  "watchdog status %s, expected exit 10" % watchdog_status)
            shown = re.sub(r"^\[watchdog [^\]]*\] ", "watchdog: ", shown)
    else:
        shown = shown_error(text, rc)
        if rc == 0 and fault.error:  # ridden out: the line that says how
            hits = [l for l in text.splitlines() if re.search(fault.error, l)]
            if hits:
                shown = re.sub(r"^\[[^\]]*\] ", "", hits[0]).strip()
        if not shown and fault.point == "rig check" and rc < 0:
            shown = "ended by the signal before the guard is installed (outputs never on)"
    row["error"] = "%s; %s" % (row["exit"], shown or "no error")
    if fault.expect == "complete":
        check(rc == 0, "the session did not complete (%s)" % row["exit"])
    else:
        check(rc != 0, "the session did not stop")
        if fault.expect == "error":
            check(bool(shown), "no error shown")
    if fault.error:
        # A session that must stop: the error it shows must name the cause (not any line of the
        # output: the demo's banner names both generator ports). One it rides out: a line of its
        # output or log says how.
        where = shown if fault.expect == "error" else text + "\n" + log_text
        check(re.search(fault.error, where) is not None,
              "the %s does not say /%s/" % ("error shown" if fault.expect == "error" else "output",
                                            fault.error))
    if fault.expect == "signal" and fault.signal != "KILL" and fault.point != "rig check":
        check("interrupted (signal)" in text + log_text, "no 'interrupted (signal)' line")
    if fault.signal != "KILL":
        # Off by msmcal itself: not left on until the watchdog fired at its exit.
        check("outputs off NOT confirmed" not in log_text and "[watchdog" not in log_text,
              "msmcal's own safe state was not confirmed (the watchdog switched the outputs off)")

    # Data lost: what the journal records, against the disk.
    if j is None:
        check(False, "no journal")
        row["lost"] = "no journal"
        row["resume"] = "-"
        return row
    frames, readings = data_lost(out, j)
    reported = sum(int(x) for x in re.findall(r"readings, \d+ clock edges, (\d+) lost", text))
    row["lost"] = "%d/%d frames, %d readings" % (len(frames), len(j["frames"]), readings)
    if fault.lost_readings:
        row["lost"] += "; %d on the wire (reported)" % reported
        check(reported == fault.lost_readings,
              "reported %d lost readings, injected %d" % (reported, fault.lost_readings))
    check(not frames and readings == 0, "lost: %s" % row["lost"])
    before = hashes(out, j["frames"])

    # Resume: the fault gone (its space freed, the demo rig's own generators).
    if fault.disk:
        os.remove(os.path.join(out, ".campaign-filler"))
    gens.send_signal(signal.SIGTERM)
    for line in gens.stdout:
        gen_log.write(line)
    gens.wait()
    gen_log.close()
    r = Session([msmcal, "resume", out], os.path.join(work, "resume.log"))
    rrc = r.wait(SESSION_DEADLINE_S)
    j2 = journal(out)
    after = hashes(out, list(before))
    changed = [f for f in before if after.get(f) != before[f]]
    complete = j2 is not None and all(
        j2["steps"].get(k) == "done" for k in ("step1", "hall_background", "step2",
                                                "session_written", "solve", "hall_calibration"))
    n = len(j2["frames"]) if j2 else 0
    if rrc == 0 and complete and not changed:
        row["resume"] = "ok: %d frames (%d kept), solved" % (n, len(before))
    else:
        row["resume"] = "FAILED: exit %d%s%s" % (rrc, "" if complete else ", incomplete",
                                                 ", %d images changed" % len(changed)
                                                 if changed else "")
        # The acquisition's error, else the finish step's (solve, Hall calibration) that failed.
        why = shown_error(r.text(), rrc) or finish_error(r.text())
        row["resume"] += " (%s)" % why
    check(rrc == 0, "resume exit %d" % rrc)
    check(complete, "journal not complete after the resume")
    check(not changed, "images recorded before the resume changed: %s" % changed[:3])
    return row


# ---------------------------------------------------------------------------------------------
# Outside: every row, the table.

def run_in_namespace(fault, args, work):
    argv = ["unshare", "-rnm", "/usr/bin/python3", os.path.abspath(__file__), "--run-row",
            fault.name, "--msmcal", args.msmcal, "--work", work]
    p = subprocess.run(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                       timeout=3 * SESSION_DEADLINE_S)
    for line in reversed(p.stdout.splitlines()):
        if line.startswith("{"):
            return json.loads(line)
    return {"name": fault.name, "what": fault.what, "ok": False, "outputs": "?", "error": "?",
            "lost": "?", "resume": "?",
            "why": ["row runner failed (exit %d): %s" % (p.returncode, p.stderr[-800:])]}


def cell(text, width):
    text = str(text).replace("|", "/")
    return text if len(text) <= width else text[:width - 1] + "…"


def print_row(row, markdown, file=sys.stdout):
    cols = [row["name"], row.get("outputs", "?"), cell(row.get("error", ""), 90),
            row.get("lost", ""), row.get("resume", ""), "passed" if row["ok"] else "FAILED"]
    print("| " + " | ".join(cols) + " |", file=file, flush=True)
    if not row["ok"]:
        for w in row["why"]:
            print("|   ↳ " + w.replace("|", "/"), file=file, flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="Faults: --list. Docs: docs/fault-campaign.md.")
    ap.add_argument("--msmcal", default=os.path.join(ROOT, "build", "app", "msmcal"))
    ap.add_argument("--only", default="", help="comma-separated fault names or globs")
    ap.add_argument("--ci", action="store_true", help="the CI-sized subset: " + ", ".join(CI_SUBSET))
    ap.add_argument("--list", action="store_true", help="list the faults and exit")
    ap.add_argument("--keep", metavar="DIR", help="keep every row's folder under DIR")
    ap.add_argument("--run-row", help=argparse.SUPPRESS)
    ap.add_argument("--work", help=argparse.SUPPRESS)
    args = ap.parse_args()
    args.msmcal = os.path.abspath(args.msmcal)
    table = {f.name: f for f in faults()}

    if args.run_row:
        try:
            row = run_row(table[args.run_row], args.msmcal, args.work)
        finally:
            # Nothing of the row outlives it, whatever went wrong (the processes are ours: this
            # runner started them, and is the subreaper of what they started).
            for p in list(CHILDREN):
                if p.poll() is None:
                    p.kill()
                    p.wait()
        print(json.dumps(row), flush=True)
        return 0
    if args.list:
        for f in table.values():
            print("%-24s %s" % (f.name, f.what))
        return 0
    if not os.access(args.msmcal, os.X_OK):
        print("fault-campaign: %s: not built (ninja -C build msmcal)" % args.msmcal)
        return 2
    chosen = list(table.values())
    if args.ci:
        chosen = [table[n] for n in CI_SUBSET]
    if args.only:
        pats = args.only.split(",")
        chosen = [f for f in chosen if any(fnmatch.fnmatch(f.name, p) for p in pats)]
    root = args.keep or tempfile.mkdtemp(prefix="msmcal-faults-")
    os.makedirs(root, exist_ok=True)
    print("| fault | outputs off | error shown | data lost (journal vs disk) | resume | result |")
    print("|---|---|---|---|---|---|", flush=True)
    passed = failed = 0
    start = time.monotonic()
    for f in chosen:
        work = os.path.join(root, f.name)
        shutil.rmtree(work, ignore_errors=True)
        row = run_in_namespace(f, args, work)
        print_row(row, True)
        passed += row["ok"]
        failed += not row["ok"]
        if row["ok"] and not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    if not args.keep and failed == 0:
        shutil.rmtree(root, ignore_errors=True)
    elif failed:
        print("(folders of the failed rows: %s)" % root)
    print("\n%d passed, %d failed  (%.0f s)" % (passed, failed, time.monotonic() - start))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
