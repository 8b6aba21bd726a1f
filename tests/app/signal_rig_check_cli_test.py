#!/usr/bin/python3
"""A signal during the rig check of `msmcal demo` (issue 17): outputs off, a clear message.

The mock generators are a separate process (`msmcal mock generators`, so their outputs can be
asked after msmcal is gone), with every output switched ON beforehand by this test (as an earlier
`gen apply --detach` or a crashed program would leave them) and unit 2's first `*IDN?` answered
2.5 s late (below the driver's 3 s timeout), which holds the rig check open while unit 1 is open
and unit 2's identify is in flight. msmcal runs with `--log-level debug`, which prints every SCPI
exchange: the signal goes when the line of unit 2's `*IDN?` is printed (no sleeps). Then, per
signal (INT, TERM, HUP, QUIT):

- msmcal ends by that signal (128 + signo, as a shell expects), having printed
  `signal N (SIGxxx): generator outputs: generator1 (...) off, confirmed; generator2 (...) off,
  confirmed`;
- the session log says `interrupted (signal) in the rig check`, and no watchdog was armed;
- `OUTP1?;:OUTP2?` on a new connection to each mock unit answers `0;0`.

Before the fix the signals' default action ended msmcal in the rig check, leaving the outputs on.
Runs in its own network namespace (GigE Vision port 3956, the rig file's ports 15025/15026).

usage: signal_rig_check_cli_test.py MSMCAL SOURCE_DIR
"""
import os
import re
import resource
import signal
import subprocess
import sys
import tempfile

PORTS = (15025, 15026)
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


from cli_testlib import Lines, fail, scpi  # tests/app/cli_testlib.py

def no_core():
    """SIGQUIT's default action dumps core: not here."""
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))


def one_signal(msmcal, rig, sim, tmp, signo):
    name = signal.Signals(signo).name
    mock = subprocess.Popen([msmcal, "mock", "generators", "--rig", rig, "--fault",
                             "unit2:delay,match=*IDN?,ms=2500"], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    try:
        for _ in range(2):
            if not mock.stdout.readline().startswith("listening on"):
                fail("mock generators did not start")
        for port in PORTS:  # left on by someone before this session
            if scpi(port, "OUTP1 ON;:OUTP2 ON;:OUTP1?;:OUTP2?") != "1;1":
                fail("port %d: could not switch the outputs on" % port)
        out = os.path.join(tmp, "session-" + name)
        demo = subprocess.Popen(
            [msmcal, "--log-level", "debug", "demo", "--out", out, "--config", sim,
             "--generator-ports", "%d,%d" % PORTS], stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, text=True, errors="replace",
            start_new_session=True, cwd=tmp, preexec_fn=no_core)
        lines = Lines(demo, "demo")
        if not lines.wait_for(r"scpi 127\.0\.0\.1:15026 << \*IDN\?", 120):
            demo.kill()
            fail("%s: the rig check never asked unit 2 for *IDN?" % name)
        os.kill(demo.pid, signo)
        try:
            rc = demo.wait(timeout=30)
        except subprocess.TimeoutExpired:
            demo.kill()
            fail("%s: msmcal did not end within 30 s of the signal" % name)
        lines.wait_done(5)
        text = lines.text()
        for port in PORTS:
            reply = scpi(port, "OUTP1?;:OUTP2?")
            if reply != "0;0":
                fail("%s: port %d: OUTP1?;:OUTP2? = %s after msmcal ended" % (name, port, reply))
        if rc != -signo:
            fail("%s: msmcal's status %s (expected the signal itself, %d)" % (name, rc, -signo))
        want = (r"signal %d \(%s\): generator outputs: \S+ \(127\.0\.0\.1:15025\) off, "
                r"confirmed; \S+ \(127\.0\.0\.1:15026\) off, confirmed$" % (signo, name))
        if not re.search(want, text, re.M):
            fail("%s: no line /%s/" % (name, want))
        if "watchdog armed" in text:
            fail("%s: a watchdog was armed before the rig check passed" % name)
        with open(os.path.join(out, "session_log.txt")) as f:
            log = f.read()
        if not re.search(r"interrupted \(signal\) in the rig check: generator outputs \S+ "
                         r"\(127\.0\.0\.1:15025\) off, confirmed; \S+ \(127\.0\.0\.1:15026\) "
                         r"off, confirmed", log):
            fail("%s: the session log does not say it was interrupted in the rig check:\n%s" %
                 (name, log))
        print("%s in the rig check: outputs off (confirmed by both units), status %d" %
              (name, rc), flush=True)
    finally:
        mock.send_signal(signal.SIGTERM)
        mock.wait()


def main():
    msmcal, src = sys.argv[1], sys.argv[2]
    rig = os.path.join(src, "config", "rig.yaml")
    with tempfile.TemporaryDirectory() as tmp:
        sim = os.path.join(tmp, "sim.yaml")
        with open(sim, "w") as f:
            f.write(SIM_YAML)
        for signo in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT):
            one_signal(msmcal, rig, sim, tmp, signo)
    print("ok")


if __name__ == "__main__":
    main()
