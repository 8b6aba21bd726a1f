#!/usr/bin/python3
"""The digital twin as separate processes (issue 20), through the msmcal binary only.

`msmcal mock rig --rig RIG --hands SOCK` serves the rig file's instruments; `msmcal mock hands`
performs set-ups on it (exit 0 once in effect; 2 on a malformed set-up, naming the field; 1 when
no twin listens); `msmcal gen apply --detach` (the real SCPI driver, another process) applies the
rig file's drives, clock and trigger arb; `msmcal mock hands --truth-out DIR` then writes the truth
for what was applied: its mirror planes are the trigger table `gen apply` wrote, and it survives
the generators' safe state (`gen off`). SIGTERM ends the twin: socket and pty symlink removed.
Runs in its own network namespace (ports 15025/15026, GigE Vision 3956).

usage: mock_rig_cli_test.py MSMCAL SOURCE_DIR
"""
import os
import select
import signal
import subprocess
import sys
import tempfile
import time


def fail(msg):
    print("FAIL: " + msg, flush=True)
    sys.exit(1)


def wait_for(pred, timeout_s, what):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if pred():
            return
        time.sleep(0.05)  # polling a condition with a deadline, not a synchronisation sleep
    fail("timed out waiting for " + what)


def hands(msmcal, sock, stdin_text=None, extra=()):
    p = subprocess.run([msmcal, "mock", "hands", "--socket", sock, *extra],
                       input=stdin_text, capture_output=True, text=True, timeout=60)
    return p.returncode, p.stdout, p.stderr


def main():
    msmcal, source = sys.argv[1], sys.argv[2]
    tmp = tempfile.mkdtemp(prefix="mock_rig_cli_")
    sock = os.path.join(tmp, "hands.sock")
    tty = os.path.join(tmp, "ttyTWIN")
    rig = os.path.join(tmp, "rig.yaml")
    text = open(os.path.join(source, "config", "rig.yaml")).read()
    # A small camera keeps the renders fast (same field of view: intrinsics halved).
    for a, b in [("width: 2448", "width: 1224"), ("height: 2048", "height: 1024"),
                 ("fx: 2000", "fx: 1000"), ("fy: 2000", "fy: 1000"),
                 ("cx: 1223.5", "cx: 611.5"), ("cy: 1023.5", "cy: 511.5"),
                 ("device: /dev/ttyACM0", "device: " + tty)]:
        if a not in text:
            fail("config/rig.yaml has no '%s'" % a)
        text = text.replace(a, b, 1)
    open(rig, "w").write(text)

    # No twin yet: a clear error, exit 1.
    code, _, err = hands(msmcal, sock, '{"msmcal_setup": 1, "kind": "setup"}')
    if code != 1 or "cannot connect" not in err:
        fail("unreachable twin: exit %d, stderr %r" % (code, err))

    twin = subprocess.Popen([msmcal, "mock", "rig", "--rig", rig, "--hands", sock,
                             "--exposure", "0.3", "--seed", "4"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        # Raw reads (a buffered readline would hide lines from select).
        buf, lines = b"", []
        deadline = time.monotonic() + 60
        fd = twin.stdout.fileno()
        while "twin: ready" not in lines:
            r, _, _ = select.select([fd], [], [], max(0.0, deadline - time.monotonic()))
            if not r:
                fail("the twin did not get ready: %r" % lines)
            chunk = os.read(fd, 4096)
            if not chunk:
                fail("the twin exited: %r %s" % (lines, twin.stderr.read().decode()))
            buf += chunk
            *done, buf = buf.split(b"\n")
            lines += [l.decode().strip() for l in done]
        if not os.path.islink(tty) or not os.path.exists(sock):
            fail("no pty symlink at %s or no socket at %s" % (tty, sock))

        setup = ('{"msmcal_setup": 1, "kind": "setup", "block": 1, "of": 3,\n'
                 ' "for": {"step": "step2", "frames": ["step2/0000.png"]}, "camera": "C2",\n'
                 ' "msm_mounted": true, "top_frame_mounted": true,\n'
                 ' "sliding_plate": {"mounted": false}, "beams_unblocked": [1, 2, 3],\n'
                 ' "drive": "scan", "changes": ["mount the MSM"], "text": "..."}\n')
        code, out, err = hands(msmcal, sock, setup)
        if code != 0 or "done" not in out:
            fail("set-up: exit %d, %r %r" % (code, out, err))
        bad = '{"msmcal_setup": 1, "kind": "setup", "sliding_plate": {"mounted": true, "pose": "x"}}'
        code, _, err = hands(msmcal, sock, bad)
        if code != 2 or "sliding_plate.pose" not in err:
            fail("malformed set-up: exit %d, stderr %r" % (code, err))
        code, _, err = hands(msmcal, sock, '{"msmcal_setup": 1, "kind": "setup", "beams_unblocked": [9]}')
        if code != 3 or "beam 9" not in err:
            fail("refused set-up: exit %d, stderr %r" % (code, err))

        # The real driver, from another process, applies the rig file's signals.
        triggers = os.path.join(tmp, "triggers.csv")
        p = subprocess.run([msmcal, "gen", "apply", "--rig", rig, "--detach",
                            "--triggers-out", triggers], capture_output=True, text=True, timeout=60)
        if p.returncode != 0:
            fail("gen apply: %d %s %s" % (p.returncode, p.stdout, p.stderr))
        p = subprocess.run([msmcal, "gen", "off", "--rig", rig], capture_output=True, text=True,
                           timeout=60)
        if p.returncode != 0:
            fail("gen off: %s" % p.stderr)
        # Truth of what was applied (the outputs are off by now).
        truth = os.path.join(tmp, "session", "truth")
        code, out, err = hands(msmcal, sock, None, ["--truth-out", truth])
        if code != 0:
            fail("truth: exit %d %r %r" % (code, out, err))
        for f in ["sim_config.yaml", "beams.csv", "mirror_planes.csv", "mirror_frame.yaml",
                  "views.yaml", "dots.csv", "hall.yaml", "pose_trajectory.csv"]:
            if not os.path.exists(os.path.join(truth, f)):
                fail("truth file %s missing" % f)
        want = [float(l.split(",")[1]) for l in open(triggers).read().splitlines()[1:] if l]
        got = [float(l.split(",")[1]) for l in open(os.path.join(truth, "mirror_planes.csv"))
               .read().splitlines()[1:] if l]
        if len(want) < 3 or len(got) != len(want):
            fail("truth has %d mirror planes, gen apply wrote %d triggers" % (len(got), len(want)))
        worst = max(abs(a - b) for a, b in zip(sorted(want), sorted(got)))
        if worst > 1e-6:
            fail("truth trigger times differ from the applied table by %g s" % worst)
        print("truth: %d mirror planes at the applied trigger times (max %.2g s)" % (len(got), worst))
    finally:
        twin.send_signal(signal.SIGTERM)
        try:
            code = twin.wait(timeout=20)
        except subprocess.TimeoutExpired:
            twin.kill()
            fail("the twin did not stop on SIGTERM")
    if code != 0:
        fail("twin exit %d: %s" % (code, twin.stderr.read().decode()))
    if os.path.exists(sock) or os.path.lexists(tty):
        fail("socket or pty symlink left behind")
    print("PASS")


main()
