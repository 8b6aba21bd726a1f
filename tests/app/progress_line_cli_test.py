#!/usr/bin/python3
"""The progress line of long commands (issue 19) through the binary: `msmcal simulate` under a
pseudo-terminal shows a line redrawn in place ("\\r... ETA ...") that reaches 100 %; the same
command with its output on pipes prints no progress at all.

Usage: progress_line_cli_test.py MSMCAL_BINARY
No sleeps: the pty is read with select() and a deadline until the child closes it.
"""
import os
import pty
import select
import shutil
import subprocess
import sys
import tempfile
import time

# A small simulator: few frames (only the rendering is timed here).
SMALL = """\
seed: 5
step1:
  poses: 2
  exposures: 1
step2:
  neutral_frames: 1
  fast_only_frames: 1
triggers:
  max_triggers: 12
  min_separation_px: 13
camera:  # half resolution, same field of view: a quarter of the pixels
  width: 1224
  height: 1024
  fx: 1000
  fy: 1000
  cx: 611.5
  cy: 511.5
"""
DEADLINE_S = 240


def fail(msg, text=""):
    print(text[-4000:])
    print("FAIL: " + msg, flush=True)
    sys.exit(1)


def run_on_pty(argv):
    pid, fd = pty.fork()
    if pid == 0:
        try:
            os.execv(argv[0], argv)
        finally:
            os._exit(127)
    out = b""
    deadline = time.monotonic() + DEADLINE_S
    while True:
        left = deadline - time.monotonic()
        if left <= 0:
            os.kill(pid, 9)
            fail("simulate on a pty did not end within %d s" % DEADLINE_S, out.decode("utf-8", "replace"))
        ready, _, _ = select.select([fd], [], [], left)
        if not ready:
            continue
        try:
            data = os.read(fd, 65536)
        except OSError:  # EIO: the child closed the terminal
            data = b""
        if not data:
            break
        out += data
    _, status = os.waitpid(pid, 0)
    os.close(fd)
    return os.waitstatus_to_exitcode(status), out.decode("utf-8", "replace")


def main():
    if len(sys.argv) != 2:
        print(__doc__)
        sys.exit(2)
    msmcal = os.path.abspath(sys.argv[1])
    work = tempfile.mkdtemp(prefix="progress_line_")
    try:
        cfg = os.path.join(work, "small.yaml")
        with open(cfg, "w") as f:
            f.write(SMALL)
        status, text = run_on_pty([msmcal, "simulate", os.path.join(work, "tty"), "--config", cfg,
                                   "--jobs", "1"])
        if status != 0:
            fail("simulate on a pty: exit status %d" % status, text)
        if "\rsimulate: 0/" not in text or "ETA" not in text:
            fail("no progress line with ETA on the terminal", text)
        lines = [l for l in text.split("\r") if l.startswith("simulate: ")]
        if len(lines) < 2:
            fail("the progress line was not redrawn (%d draws)" % len(lines), text)
        last = lines[-1].split("\x1b[K")[0]
        total = last.split("/")[1].split(" ")[0]
        if not last.startswith("simulate: %s/%s frames rendered (100%%)" % (total, total)):
            fail("the last draw is not 100 %%: %r" % last, text)

        p = subprocess.run([msmcal, "simulate", os.path.join(work, "pipe"), "--config", cfg,
                            "--jobs", "1"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           timeout=DEADLINE_S)
        both = p.stdout.decode("utf-8", "replace") + p.stderr.decode("utf-8", "replace")
        if p.returncode != 0:
            fail("simulate on pipes: exit status %d" % p.returncode, both)
        if "ETA" in both or "\r" in both or "frames rendered" in both:
            fail("a progress line was printed on a pipe", both)
        print("ok: %d draws on the terminal ending at %s/%s (100%%), none on pipes" %
              (len(lines), total, total))
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
