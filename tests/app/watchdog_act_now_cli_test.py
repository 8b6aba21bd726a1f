#!/usr/bin/python3
"""The watchdog asked to act while msmcal is alive (issue 17, docs/watchdog.md).

msmcal's own safe state cannot be confirmed: the mock generators (a separate process, serving one
SCPI connection at a time, `--second-connection queue`, the strictest 33500) close unit 1's
connection at its first two `OUTP1 OFF;:OUTP2 OFF` (the message not executed: a cable pulled
under the safe state), so the driver's SafeState() fails on its connection and on its reconnect,
with unit 1's outputs still on. msmcal must then close its own generator connections, ask its
watchdog through the life pipe to act now, wait for its verdict and say it loudly, with exit
status 76 (the watchdog confirmed every output off). Three paths, each with fresh mocks:

- `gen apply` + SIGINT (the signal guard's action), synchronised on its "Ctrl-C" line;
- `msmcal demo` + SIGINT in step 1 (the session's guard), synchronised on "step 1: frame 1/";
- `msmcal demo --mock-fault camera:lost@3` (the session's error path on the main thread).

Each time: exit status 76 and the loud line; the watchdog's lines ("process P asked the watchdog to
act") for both units, confirmed, in the log; the watchdog reaped by msmcal (no orphan left to
the test, which is a child subreaper); `OUTP1?;:OUTP2?` = `0;0` on a new connection to each unit.
Before the change msmcal exited 75 or 1 and the watchdog fired only at its exit (or, on the error
path, while msmcal still held its connections). Own network namespace (ports 15025/15026, 3956).

usage: watchdog_act_now_cli_test.py MSMCAL SOURCE_DIR
"""
import ctypes
import os
import re
import signal
import subprocess
import sys
import tempfile
import time

PORTS = (15025, 15026)
PR_SET_CHILD_SUBREAPER = 36
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
LOUD = re.compile(r"safe state NOT CONFIRMED by msmcal itself; the watchdog \(pid (\d+), exit "
                  r"status 10\), asked to act on new connections, confirmed every output off")


from cli_testlib import Lines, fail, scpi  # tests/app/cli_testlib.py

def orphans():
    """Children of this test other than the mock (a watchdog msmcal did not reap)."""
    me = os.getpid()
    with open("/proc/%d/task/%d/children" % (me, me)) as f:
        return [int(p) for p in f.read().split()]


def run_case(name, msmcal, rig, argv, sync, signo, log_of):
    mock = subprocess.Popen(
        [msmcal, "mock", "generators", "--rig", rig, "--second-connection", "queue",
         "--fault", "unit1:drop,match=OUTP1 OFF;", "--fault", "unit1:drop,match=OUTP1 OFF;"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        for _ in range(2):
            if not mock.stdout.readline().startswith("listening on"):
                fail("%s: mock generators did not start" % name)
        t0 = time.monotonic()
        proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, text=True, errors="replace",
                                start_new_session=True)
        lines = Lines(proc, name)
        if sync and not lines.wait_for(sync, 180):
            proc.kill()
            fail("%s: never printed /%s/" % (name, sync))
        if signo:
            os.kill(proc.pid, signo)
        try:
            rc = proc.wait(timeout=120)
        except subprocess.TimeoutExpired:
            proc.kill()
            fail("%s: msmcal did not end" % name)
        lines.wait_done(5)
        text = lines.text()
        outputs = [scpi(p, "OUTP1?;:OUTP2?") for p in PORTS]
        if outputs != ["0;0", "0;0"]:
            fail("%s: outputs after msmcal ended: %s" % (name, outputs))
        if rc != 76:
            fail("%s: exit status %s (expected 76: msmcal's own safe state not confirmed, the "
                 "watchdog's confirmed)" % (name, rc))
        m = LOUD.search(text)
        if not m:
            fail("%s: no loud line saying the watchdog acted and confirmed" % name)
        with open(log_of()) as f:
            log = f.read()
        for port in PORTS:
            want = (r"asked the watchdog to act \(its own safe state was not confirmed\): \S+ "
                    r"\(127\.0\.0\.1:%d\) outputs off, confirmed" % port)
            if not re.search(want, log):
                fail("%s: no watchdog line for port %d in %s:\n%s" % (name, port, log_of(), log))
        if int(m.group(1)) in orphans():
            fail("%s: the watchdog was not reaped by msmcal" % name)
        print("%s: outputs off by the watchdog, confirmed; msmcal exit 76 (%.1f s)" %
              (name, time.monotonic() - t0), flush=True)
    finally:
        mock.send_signal(signal.SIGTERM)
        mock.wait()


def main():
    msmcal, src = sys.argv[1], sys.argv[2]
    rig = os.path.join(src, "config", "rig.yaml")
    if ctypes.CDLL(None, use_errno=True).prctl(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0) != 0:
        fail("prctl(PR_SET_CHILD_SUBREAPER) failed")
    with tempfile.TemporaryDirectory() as tmp:
        sim = os.path.join(tmp, "sim.yaml")
        with open(sim, "w") as f:
            f.write(SIM_YAML)
        wlog = os.path.join(tmp, "apply-watchdog.log")
        run_case("gen-apply-SIGINT", msmcal, rig,
                 [msmcal, "gen", "apply", "--rig", rig, "--watchdog-log", wlog],
                 r"^Ctrl-C \(SIGINT\)", signal.SIGINT, lambda: wlog)
        out = os.path.join(tmp, "demo-signal")
        run_case("demo-step1-SIGINT", msmcal, rig,
                 [msmcal, "demo", "--out", out, "--config", sim, "--generator-ports", "15025,15026"],
                 r"\] step 1: frame 1/", signal.SIGINT,
                 lambda: os.path.join(out, "session_log.txt"))
        out2 = os.path.join(tmp, "demo-error")
        run_case("demo-camera-lost", msmcal, rig,
                 [msmcal, "demo", "--out", out2, "--config", sim, "--generator-ports",
                  "15025,15026", "--mock-fault", "camera:lost@3"], None, 0,
                 lambda: os.path.join(out2, "session_log.txt"))
    print("ok")


if __name__ == "__main__":
    main()
