#!/usr/bin/python3
"""The generator watchdog through the msmcal binary (issue 17).

`msmcal mock generators` serves the rig's two mock 33520B units (a separate process, so they
outlive the kill); `msmcal gen apply` turns every output on with its watchdog armed and is
SIGKILLed. The test is a child subreaper, so the orphaned watchdog becomes its child: it waits
for the watchdog's exit (bounded by a pidfd), then asks the mocks over their own SCPI port that every output
is off, and checks that this happened within 2 s of the kill and that the watchdog's report is in
the log. Then the clean path: SIGINT to `gen apply` (its own guard switches the outputs off and
stands the watchdog down): the watchdog exits 0 and writes nothing, and the --transcript file
ends with the safe state's exchange (flushed before the signal ends the process; it used to stop
at the apply). Runs in its own network
namespace (the rig file's ports 15025/15026).

usage: gen_watchdog_cli_test.py MSMCAL SOURCE_DIR
"""
import ctypes
import os
import select
import signal
import subprocess
import sys
import tempfile
import time

from cli_testlib import fail, scpi, wait_child  # tests/app/cli_testlib.py

PR_SET_CHILD_SUBREAPER = 36


def watchdog_of(pid):
    """The watchdog: the one child of `pid`'s main thread (msmcal spawns it from there)."""
    with open("/proc/%d/task/%d/children" % (pid, pid)) as f:
        children = [int(p) for p in f.read().split()]
    if len(children) != 1:
        fail("expected exactly one child (the watchdog) of msmcal %d, got %s" % (pid, children))
    return children[0]


def apply(msmcal, rig, log, transcript=None):
    extra = ["--transcript", transcript] if transcript else []
    child = subprocess.Popen([msmcal, "gen", "apply", "--rig", rig, "--watchdog-log", log] + extra,
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                             start_new_session=True)
    for line in child.stdout:
        print("apply| " + line.rstrip("\n"), flush=True)
        if line.startswith("Ctrl-C (SIGINT)"):
            return child
    fail("gen apply ended before its outputs were on (exit %s)" % child.wait())


def main():
    msmcal, src = sys.argv[1], sys.argv[2]
    rig = os.path.join(src, "config", "rig.yaml")
    if ctypes.CDLL(None, use_errno=True).prctl(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0) != 0:
        fail("prctl(PR_SET_CHILD_SUBREAPER) failed")
    mock = subprocess.Popen([msmcal, "mock", "generators", "--rig", rig], stdout=subprocess.PIPE,
                            text=True)
    for _ in range(2):
        if not mock.stdout.readline().startswith("listening on"):
            fail("mock generators did not start")
    tmp = tempfile.mkdtemp()
    try:
        # SIGKILL: the watchdog switches everything off.
        log = os.path.join(tmp, "kill.log")
        child = apply(msmcal, rig, log)
        for port in (15025, 15026):
            if scpi(port, "OUTP1?;:OUTP2?") != "1;1":
                fail("port %d: outputs not on before the kill" % port)
        watchdog_pid = watchdog_of(child.pid)
        killed_at = time.monotonic()
        os.kill(child.pid, signal.SIGKILL)
        child.stdout.close()
        child.wait()
        status = wait_child(watchdog_pid, 5.0)
        took = time.monotonic() - killed_at
        for port in (15025, 15026):
            reply = scpi(port, "OUTP1?;:OUTP2?")
            if reply != "0;0":
                fail("port %d: OUTP1?;:OUTP2? = %s after the watchdog" % (port, reply))
        if took >= 2.0:
            fail("outputs off %.3f s after the kill (limit 2 s)" % took)
        if not os.WIFEXITED(status) or os.WEXITSTATUS(status) != 10:
            fail("watchdog wait status %d (expected exit 10: fired, confirmed)" % status)
        with open(log) as f:
            text = f.read()
        for unit, port in (("unit1", 15025), ("unit2", 15026)):
            if "%s (127.0.0.1:%d) outputs off, confirmed" % (unit, port) not in text:
                fail("no report line for %s in the log:\n%s" % (unit, text))
        print("SIGKILL: outputs off %.0f ms after the kill; watchdog exit 10" % (took * 1e3))

        # SIGINT: msmcal's own guard; the watchdog stands down and writes nothing.
        log = os.path.join(tmp, "int.log")
        transcript = os.path.join(tmp, "int-transcript.txt")
        child = apply(msmcal, rig, log, transcript)
        watchdog_pid = watchdog_of(child.pid)
        wd_fd = os.pidfd_open(watchdog_pid)
        os.killpg(child.pid, signal.SIGINT)  # as Ctrl-C: the whole process group
        for line in child.stdout:
            print("apply| " + line.rstrip("\n"), flush=True)
        status = child.wait()
        if status != -signal.SIGINT:
            fail("gen apply after SIGINT: status %s (expected killed by SIGINT)" % status)
        if not select.select([wd_fd], [], [], 0)[0]:
            fail("the watchdog outlived a clean run")
        os.close(wd_fd)
        for port in (15025, 15026):
            if scpi(port, "OUTP1?;:OUTP2?") != "0;0":
                fail("port %d: outputs on after SIGINT" % port)
        if os.path.exists(log):
            with open(log) as f:
                fail("the watchdog reported after a clean run:\n" + f.read())
        # The transcript ends with the safe state's exchange, written before the process ended
        # by the signal: each unit switched off and confirmed "0;0".
        with open(transcript) as f:
            exchange = [l.split(" ", 1)[1] for l in f.read().splitlines()]
        for unit in ("unit1", "unit2"):
            want = ["%s << OUTP1 OFF;:OUTP2 OFF" % unit, "%s << OUTP1?;:OUTP2?" % unit,
                    "%s >> 0;0" % unit]
            mine = [l for l in exchange if l.startswith(unit + " ")]
            if mine[-3:] != want:
                fail("the transcript does not end with %s's safe state: %s" % (unit, mine[-3:]))
        print("SIGINT: outputs off by msmcal's guard; watchdog stood down")
    finally:
        mock.send_signal(signal.SIGTERM)
        mock.wait()
        for name in os.listdir(tmp):
            os.remove(os.path.join(tmp, name))
        os.rmdir(tmp)
    print("ok")


if __name__ == "__main__":
    main()
