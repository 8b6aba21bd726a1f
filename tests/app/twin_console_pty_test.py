#!/usr/bin/python3
"""The console operator of a lab session on the twin through a pseudo-terminal (issue 20): the
new prompt policy, end to end through the msmcal binary, as a person at the rig meets it.

`msmcal mock rig --rig RIG --hands SOCK --hall-link TTY` serves the twin; `msmcal plan --rig RIG
--out PLAN --setups SETUPS` designs the plan and writes its set-ups as JSON lines; `msmcal session
run --rig RIG --plan PLAN --out OUT --mcu TTY` (the default operator: console) runs on a pty. At
each prompt "[k/N]" the test is the person: it performs set-up k on the twin (`msmcal mock hands`
with line k of SETUPS on stdin), then presses Enter.

Checked: exactly one prompt per set-up of the plan (N = the set-ups `plan` announced and wrote),
in order, each block's text the set-up's own; the frames the blocks list cover every frame of
the plan's session.yaml; repeated exposures never prompt (each step-1 scene is taken twice
here, so there are at most half as many step-1 prompts as step-1 frames, and a block of several
frames says they are taken without another prompt); exit status 0 with the outputs off and
session.yaml written (seen: 13 prompts, 10 of them for 20 step-1 frames; about 2 min).
Runs in its own network namespace (ports 15025/15026, GigE Vision 3956). No sleeps: every wait
is select() on the pty or a line of a process's output, with a deadline.

usage: twin_console_pty_test.py MSMCAL SOURCE_DIR
"""
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

from cli_testlib import Lines, PtyChild, fail  # tests/app/cli_testlib.py

PROMPT = "[Enter] ready  [r] repeat instructions  [q] abort > "
PROMPT_DEADLINE_S = 240  # per prompt (frames of the previous set-up on a loaded machine)
END_DEADLINE_S = 400     # after the last prompt: step 2, the solve, the Hall calibration


def make_rig(source, tmp):
    text = open(os.path.join(source, "config", "rig.yaml")).read()
    # Short Hall recordings, 4 poses, each step-1 frame taken twice (repeated exposures), few
    # triggers and step-2 frames; the rig file keeps the lab's hall_mcu.device.
    for a, b in [("stall_timeout_ms: 500", "stall_timeout_ms: 2000"),  # a loaded machine
                 # the camera at half resolution, same field of view: a quarter of the pixels
                 ("width: 2448", "width: 1224"), ("height: 2048", "height: 1024"),
                 ("fx: 2000", "fx: 1000"), ("fy: 2000", "fy: 1000"),
                 ("cx: 1223.5", "cx: 611.5"), ("cy: 1023.5", "cy: 511.5"),
                 ("hall_background_s: 12", "hall_background_s: 1"),
                 ("hall_actual_min_s: 15", "hall_actual_min_s: 1"),
                 ("  poses: 7", "  poses: 4"),
                 ("  exposures: 3 ", "  exposures: 2 "),
                 ("spacing: 0.25", "spacing: 0.6"),
                 ("max_triggers: 2000", "max_triggers: 12"),
                 ("neutral_frames: 2", "neutral_frames: 1"),
                 ("fast_only_frames: 3", "fast_only_frames: 1")]:
        if a not in text:
            fail("config/rig.yaml has no '%s'" % a)
        text = text.replace(a, b, 1)
    rig = os.path.join(tmp, "rig.yaml")
    open(rig, "w").write(text)
    return rig


class Child(PtyChild):
    """msmcal on a pty (scripts/msmcal_harness.py PtyChild)."""

    def next_prompt_or_end(self, seconds):
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
                fail("neither a prompt nor the end within %d s\n%s" % (seconds, self.out[-4000:]))

    def answer(self, text):
        os.write(self.fd, (text + "\n").encode())

    def finish(self, seconds):
        deadline = time.monotonic() + seconds
        while not self.eof:
            if not self._read(deadline) and not self.eof:
                fail("msmcal did not end within %d s\n%s" % (seconds, self.out[-4000:]))
        _, status = os.waitpid(self.pid, 0)
        os.close(self.fd)
        return os.waitstatus_to_exitcode(status)


def main():
    if len(sys.argv) != 3:
        print(__doc__)
        sys.exit(2)
    msmcal, source = os.path.abspath(sys.argv[1]), sys.argv[2]
    tmp = tempfile.mkdtemp(prefix="twin_console_pty_")
    sock, tty = os.path.join(tmp, "hands.sock"), os.path.join(tmp, "tty")
    rig = make_rig(source, tmp)
    plan, setups_file = os.path.join(tmp, "plan"), os.path.join(tmp, "setups.jsonl")
    out = os.path.join(tmp, "session")
    p = subprocess.run([msmcal, "plan", "--rig", rig, "--out", plan, "--setups", setups_file],
                       capture_output=True, text=True, timeout=120)
    if p.returncode != 0:
        fail("plan: %s %s" % (p.stdout, p.stderr))
    announced = re.search(r"^prompts: (\d+) set-ups", p.stdout, re.M)
    setups = [json.loads(l) for l in open(setups_file).read().splitlines() if l]
    if not announced or int(announced.group(1)) != len(setups):
        fail("plan announced %s prompts, wrote %d set-ups:\n%s" %
             (announced and announced.group(1), len(setups), p.stdout))

    twin = subprocess.Popen([msmcal, "mock", "rig", "--rig", rig, "--hands", sock,
                             "--hall-link", tty], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    twin_lines = Lines(twin, "twin")
    try:
        if not twin_lines.wait_for(r"^twin: ready$", 120):
            fail("the twin did not get ready")
        child = Child([msmcal, "session", "run", "--rig", rig, "--plan", plan, "--out", out,
                       "--mcu", tty])
        prompts = step1_prompts = 0
        covered = {"step1": 0, "step2": 0}
        while True:
            chunk = child.next_prompt_or_end(PROMPT_DEADLINE_S)
            if chunk is None:
                break
            found = re.findall(r"=== \[(\d+)/(\d+)\] (.*?) ===", chunk)
            if not found:
                fail("prompt %d without instructions before it\n%s" % (prompts + 1, chunk))
            k, n, title = int(found[-1][0]), int(found[-1][1]), found[-1][2]
            prompts += 1
            if k != prompts or n != len(setups):
                fail("prompt %d shows block [%d/%d]; the plan has %d set-ups" %
                     (prompts, k, n, len(setups)))
            s = setups[k - 1]
            if s["text"].strip() not in chunk.replace("\r", ""):
                fail("block %d's text is not the set-up's:\n%s\n---\n%s" % (k, chunk, s["text"]))
            step, frames = s["for"]["step"], s["for"].get("frames", [])
            if step in covered:
                covered[step] += len(frames)
                more = re.search(r" and (\d+) more at this set-up", title)
                if len(frames) != 1 + (int(more.group(1)) if more else 0):
                    fail("block %d lists %d frames, its title says %r" % (k, len(frames), title))
                if len(frames) > 1 and ("%d frames are taken at this set-up without another "
                                        "prompt" % len(frames)) not in chunk:
                    fail("block %d of %d frames does not say they need no prompt:\n%s" %
                         (k, len(frames), chunk))
            if step == "step1":
                step1_prompts += 1
            # The person performs the set-up on the twin, then confirms.
            h = subprocess.run([msmcal, "mock", "hands", "--socket", sock],
                               input=json.dumps(s) + "\n", capture_output=True, text=True,
                               timeout=120)
            if h.returncode != 0:
                fail("mock hands for block %d: %d %s %s" % (k, h.returncode, h.stdout, h.stderr))
            child.answer("")
        status = child.finish(END_DEADLINE_S)
        text = child.out
    finally:
        twin.send_signal(signal.SIGTERM)
        try:
            twin.wait(timeout=60)
        except subprocess.TimeoutExpired:
            twin.kill()
            twin.wait()
    if status != 0:
        fail("session run exited with %d\n%s" % (status, text[-4000:]))
    if prompts != len(setups):
        fail("%d prompts for %d set-ups" % (prompts, len(setups)))
    if "safe state: generator outputs off (confirmed)" not in text:
        fail("no confirmed safe state at the end\n" + text[-4000:])
    if not os.path.exists(os.path.join(out, "session.yaml")):
        fail("no session.yaml written")
    # The plan's frames (the gate may still reject a frame: that is not the prompts' business).
    with open(os.path.join(plan, "session.yaml")) as f:
        listed = re.findall(r"file: (step[12])/\d+\.png", f.read())
    n1, n2 = listed.count("step1"), listed.count("step2")
    if covered["step1"] != n1 or covered["step2"] != n2:
        fail("the prompted blocks cover %d step-1 and %d step-2 frames; the plan lists %d and "
             "%d" % (covered["step1"], covered["step2"], n1, n2))
    if not 0 < step1_prompts * 2 <= n1:
        fail("%d step-1 prompts for %d step-1 frames (2 exposures each): a prompt per repeated "
             "exposure?" % (step1_prompts, n1))
    print("ok: %d prompts for %d set-ups (%d step-1 prompts for %d step-1 frames, %d step-2 "
          "frames), exit 0, outputs off" % (prompts, len(setups), step1_prompts, n1, n2))
    shutil.rmtree(tmp, ignore_errors=True)
    print("PASS")


if __name__ == "__main__":
    main()
