#!/usr/bin/python3
"""Acceptance test of the guided mode (issue 9): `msmcal demo --guided` driven through a
pseudo-terminal, answering at its prompts.

Usage: guided_pty_test.py MSMCAL_BINARY complete|abort|interrupt
(run in its own network namespace: the demo rig serves GigE Vision on 127.0.0.1:3956).

complete: answers Enter at every prompt (once "r" first, and checks the instructions are shown
  again); checks each prompt names the right action (first: mount the sliding plate at pose 1;
  the background recording: remove the mirror's top frame, asked after the last step-1 frame and
  before the recording starts; step 2: mount the top frame), one prompt per set-up (the frames
  each block lists cover session.yaml's frames; repeated exposures never prompt: at most one
  step-1 prompt per 3 step-1 frames), then exit status 0, one preview per
  accepted frame (exactly the frames session.yaml lists), live figures and the report printed.
abort: answers Enter until the first step-2 frame prompt, then "q": exit status non-zero, the
  generator outputs switched off (safe state), the abort in session_log.txt and in the journal's
  events (session.db), no session.yaml.
interrupt: types Ctrl-C (the terminal's SIGINT) at the second step-1 prompt: the process ends by
  SIGINT after switching the generator outputs off, and the session log says so.

No sleeps: every wait is select() on the pty with a deadline.
"""
import os
import re
import shutil
import sqlite3
import sys
import tempfile
import time

from cli_testlib import PtyChild  # tests/app/cli_testlib.py

PROMPT = "[Enter] ready  [r] repeat instructions  [q] abort > "
PROMPT_DEADLINE_S = 180  # per prompt (the first includes starting the rig on a busy machine)
END_DEADLINE_S = 300     # after the last prompt (solve + Hall calibration for `complete`)

# The tiny simulator (config/sim.yaml keys): 4 poses, 1 neutral, 2 fast-only frames. 30 triggers
# so that the Hall calibration after the session has enough poses for its model.
TINY = """\
seed: 3
step1:
  poses: 4
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


def fail(msg, output=None):
    if output is not None:
        print("---- output of msmcal (last 6000 chars) ----")
        print(output[-6000:])
    print("FAIL: " + msg, flush=True)
    sys.exit(1)


class Child(PtyChild):
    """msmcal on a pty (scripts/msmcal_harness.py PtyChild)."""

    def until(self, marker, seconds):
        """Text from the last consumed position up to and including `marker`."""
        deadline = time.monotonic() + seconds
        while True:
            i = self.out.find(marker, self.pos)
            if i >= 0:
                chunk = self.out[self.pos:i + len(marker)]
                self.pos = i + len(marker)
                return chunk
            if self.eof or not self._read(deadline):
                fail("no %r within %d s (eof=%s)" % (marker, seconds, self.eof), self.out)

    def next_prompt_or_end(self, seconds):
        """The chunk up to the next prompt, or None when the child ended the output first."""
        deadline = time.monotonic() + seconds
        while True:
            i = self.out.find(PROMPT, self.pos)
            if i >= 0:
                chunk = self.out[self.pos:i + len(PROMPT)]
                self.pos = i + len(PROMPT)
                return chunk
            if self.eof:
                return None
            if not self._read(deadline) and not self.eof:
                fail("neither a prompt nor the end within %d s" % seconds, self.out)

    def answer(self, text):
        os.write(self.fd, (text + "\n").encode())

    def finish(self, seconds):
        """Reads to EOF; returns the exit status."""
        deadline = time.monotonic() + seconds
        while not self.eof:
            if not self._read(deadline) and not self.eof:
                fail("msmcal did not end within %d s" % seconds, self.out)
        _, status = os.waitpid(self.pid, 0)
        os.close(self.fd)
        return os.waitstatus_to_exitcode(status)


def header(chunk):
    """The last instruction header "[k/N] title" in a chunk."""
    found = re.findall(r"=== \[(\d+)/(\d+)\] (.*?) ===", chunk)
    return found[-1] if found else None


def session_files(folder):
    with open(os.path.join(folder, "session.yaml")) as f:
        return sorted(re.findall(r"file: (step[12]/\d+\.png)", f.read()))


def run(msmcal, mode):
    work = tempfile.mkdtemp(prefix="guided_pty_")
    try:
        cfg = os.path.join(work, "tiny.yaml")
        with open(cfg, "w") as f:
            f.write(TINY)
        out = os.path.join(work, "session")
        child = Child([msmcal, "demo", "--guided", "--config", cfg, "--out", out])

        prompts = 0
        repeated = False
        step1_seen = 0
        background_seen = actual_seen = False
        total = None
        # The prompt policy (issue 20): one prompt per physical set-up; the frames a block lists
        # ("frame k of N and M more at this set-up") are all taken after that one prompt.
        step1_prompts = step1_covered = step2_covered = 0
        while True:
            chunk = child.next_prompt_or_end(PROMPT_DEADLINE_S)
            if chunk is None:
                break
            prompts += 1
            h = header(chunk)
            if h is None:
                fail("prompt %d without instructions before it" % prompts, child.out)
            k, n, title = int(h[0]), int(h[1]), h[2]
            total = n if total is None else total
            if n != total:
                fail("block count changed from %d to %d" % (total, n), child.out)

            if prompts == 1:
                if not title.startswith("Step 1, frame 1 of"):
                    fail("first prompt is not step 1, frame 1: %r" % title, child.out)
                if "Mount the sliding plate at pose 1 of 4" not in chunk:
                    fail("first prompt does not say to mount the sliding plate at pose 1", chunk)
            more = re.search(r" and (\d+) more at this set-up", title)
            covered = 1 + (int(more.group(1)) if more else 0)
            if title.startswith("Step 1, frame"):
                step1_prompts += 1
                step1_covered += covered
                if covered > 1 and \
                        "%d frames are taken at this set-up without another prompt" % covered \
                        not in chunk:
                    fail("a step-1 block of %d frames does not say so" % covered, chunk)
            if title.startswith("Step 2, frame"):
                step2_covered += covered
            if title.startswith("Step 1, frame"):
                step1_seen += 1
                if "MSM not mounted" not in chunk:
                    fail("step-1 prompt does not say the MSM is not mounted", chunk)
            if "background Hall recording" in title:
                background_seen = True
                if "Remove the mirror's top frame" not in chunk:
                    fail("background prompt does not say to remove the top frame", chunk)
                if "Hall: background recording on" in child.out:
                    fail("background recording started before the operator confirmed", child.out)
                if step1_seen == 0:
                    fail("background prompt before any step-1 frame", child.out)
            if title.startswith("Step 2 set-up"):
                actual_seen = True
                if not background_seen:
                    fail("step 2 set-up asked before the background recording", child.out)
                if "Mount the mirror's top frame" not in chunk:
                    fail("step-2 set-up does not say to mount the top frame", chunk)
            if title.startswith("Step 2, frame") and not actual_seen:
                fail("step-2 frame before the step-2 set-up", child.out)

            if mode == "abort" and title.startswith("Step 2, frame"):
                child.answer("q")
                break
            if mode == "interrupt" and step1_seen == 2:
                os.write(child.fd, b"\x03")  # the line discipline sends SIGINT
                break
            if mode == "complete" and prompts == 2 and not repeated:
                # Ask for the instructions again: the same block, then the prompt again.
                child.answer("r")
                again = child.until(PROMPT, PROMPT_DEADLINE_S)
                if header(again) != h:
                    fail("'r' did not repeat the instructions %r" % (h,), again)
                repeated = True
            child.answer("")

        status = child.finish(END_DEADLINE_S)
        text = child.out

        if mode == "complete":
            if status != 0:
                fail("exit status %d" % status, text)
            if not repeated or not background_seen or not actual_seen:
                fail("prompts missed: repeated=%s background=%s actual=%s" %
                     (repeated, background_seen, actual_seen), text)
            if prompts != total:
                fail("%d prompts answered, %s announced" % (prompts, total), text)
            if not os.path.exists(os.path.join(out, "session.yaml")):
                fail("no session.yaml", text)
            accepted = session_files(out)
            # No prompt for repeated exposures: the step-1 prompts cover every step-1 frame,
            # each block its repeated exposures (the simulator takes each step-1 frame 3 times),
            # so there are fewer step-1 prompts than frames; step 2's blocks cover step 2.
            n1 = sum(1 for f in accepted if f.startswith("step1/"))
            n2 = len(accepted) - n1
            if step1_covered != n1 or step2_covered != n2:
                fail("prompted blocks cover %d step-1 and %d step-2 frames; session.yaml lists "
                     "%d and %d" % (step1_covered, step2_covered, n1, n2), text)
            if not 0 < step1_prompts * 3 <= n1:
                fail("%d step-1 prompts for %d step-1 frames (3 exposures each): a prompt per "
                     "repeated exposure?" % (step1_prompts, n1), text)
            previews = sorted(os.listdir(os.path.join(out, "previews")))
            expected = sorted(f.replace("/", "_").replace(".png", ".jpg") for f in accepted)
            if previews != expected:
                fail("previews %s, expected one per accepted frame %s" % (previews, expected), text)
            if "live: step1/0000.png" not in text or "ACCEPTED | totals:" not in text:
                fail("no live figures printed", text)
            if "== Table I style" not in text or "report: " not in text:
                fail("the report was not printed", text)
            print("ok: %d prompts answered (one 'r'; %d for %d step-1 frames), %d frames "
                  "accepted with previews, exit 0" % (prompts, step1_prompts, n1, len(accepted)))
        elif mode == "interrupt":
            if status not in (-2, 130):
                fail("interrupted session: exit status %d, expected SIGINT (-2) or 130" % status,
                     text)
            with open(os.path.join(out, "session_log.txt")) as f:
                log = f.read()
            if "interrupted (signal)" not in log or "generator outputs off" not in log:
                fail("session_log.txt does not record the interrupt and the safe state", log)
            print("ok: Ctrl-C at a step-1 prompt: status %d, outputs off" % status)
        else:
            if status == 0:
                fail("aborted session exited with status 0", text)
            if "safe state: generator outputs off" not in text:
                fail("no safe state after the abort", text)
            if "operator aborted" not in text:
                fail("the abort is not reported", text)
            with open(os.path.join(out, "session_log.txt")) as f:
                if "operator aborted" not in f.read():
                    fail("session_log.txt does not record the abort", text)
            db = sqlite3.connect(os.path.join(out, "session.db"))
            rows = db.execute(
                "SELECT kind, message FROM events WHERE message LIKE '%operator aborted%'").fetchall()
            safe = db.execute(
                "SELECT count(*) FROM events WHERE message LIKE '%generator outputs off%'").fetchone()
            db.close()
            if not rows:
                fail("the journal's events do not record the abort", text)
            if safe[0] == 0:
                fail("the journal's events do not record the safe state", text)
            if os.path.exists(os.path.join(out, "session.yaml")):
                fail("an aborted session wrote session.yaml", text)
            print("ok: aborted at a step-2 prompt after %d prompts: exit %d, outputs off, "
                  "journal event %r" % (prompts, status, rows[0]))
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main():
    if len(sys.argv) != 3 or sys.argv[2] not in ("complete", "abort", "interrupt"):
        print(__doc__)
        sys.exit(2)
    run(os.path.abspath(sys.argv[1]), sys.argv[2])


if __name__ == "__main__":
    main()
