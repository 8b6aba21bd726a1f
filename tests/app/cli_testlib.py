"""What the CLI tests in tests/app share: fail(), and from scripts/msmcal_harness.py (shared with
the fault campaign) one SCPI query on a new connection (the mock generators' outputs as a client
sees them), a process's output lines collected by a thread to wait on (a line, not a sleep) and a
bounded wait for a process by its pidfd, a program on a pty (PtyChild)."""

import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..",
                                "scripts"))
from msmcal_harness import Lines, PtyChild, scpi, wait_pid  # noqa: E402,F401  (re-exported)


def fail(msg):
    print("FAIL: " + msg, flush=True)
    sys.exit(1)


def wait_child(pid, deadline_s):
    """Waits for child `pid` to end (bounded by a pidfd); its wait status, or the test fails."""
    status = wait_pid(pid, deadline_s)
    if status is None:
        fail("process %d did not end within %.1f s (or is not ours)" % (pid, deadline_s))
    return status
