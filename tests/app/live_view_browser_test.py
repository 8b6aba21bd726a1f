#!/usr/bin/python3
"""Acceptance test of the live view (issue 19): a real browser (headless Chromium driven by
Selenium through /usr/bin/chromedriver) runs `msmcal demo --guided --ui web:0` from the page.

Usage: live_view_browser_test.py MSMCAL_BINARY OUT_DIR complete|abort
(run in its own network namespace: the demo rig serves GigE Vision on 127.0.0.1:3956, and the
browser, the page and msmcal share the namespace's loopback).

complete: at step 1, frame 1 (before any frame was taken, so the image comes from the preview
  pump) the camera image is shown, the instruction is the console's block, the generator
  outputs indicator is on, and OUT_DIR/live_view_step1.png is the page's screenshot; a second
  tab only watches (its buttons disabled, "watching"); Repeat shows the same block again; a
  reload keeps control and aborts nothing; then Ready at every instruction until the state says
  `done`: exit status 0, session.yaml written, the figures shown, outputs off.
abort: Ready until the first step-2 frame's instruction, then Abort: the state says `aborted`,
  exit status non-zero, the mock generators answered the last output queries with every output
  off (generators_transcript.txt: `OUTP1?;:OUTP2?` -> `0;0` on both units after the last `ON`),
  the safe state and the abort in session_log.txt and in the journal, no session.yaml.

No sleeps: msmcal's output is read by a thread and waited on with a condition; the page is
waited on with WebDriverWait (a condition polled until a deadline).
"""
import os
import re
import shutil
import sqlite3
import subprocess
import sys
import tempfile
import threading
import time

from selenium import webdriver
from selenium.common.exceptions import StaleElementReferenceException
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import WebDriverWait

PROMPT_DEADLINE_S = 240  # per instruction (the first includes starting the rig on a busy machine)
END_DEADLINE_S = 400     # after the last instruction (solve + Hall calibration for `complete`)

# The tiny simulator of tests/app/guided_pty_test.py, one exposure per step 1 frame (the page is
# under test, not the averaging; guided_pty_test.py keeps the repeated exposures).
TINY = """\
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


class Msmcal:
    """msmcal with its output collected by a thread; wait_for() waits on a condition."""

    def __init__(self, argv):
        self.proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     stdin=subprocess.DEVNULL)
        self.out = ""
        self.ended = False
        self.cond = threading.Condition()
        self.thread = threading.Thread(target=self._read, daemon=True)
        self.thread.start()

    def _read(self):
        for raw in iter(lambda: self.proc.stdout.read1(65536), b""):
            with self.cond:
                self.out += raw.decode("utf-8", "replace")
                self.cond.notify_all()
        with self.cond:
            self.ended = True
            self.cond.notify_all()

    def wait_for(self, pattern, seconds):
        deadline = time.monotonic() + seconds
        with self.cond:
            while True:
                m = re.search(pattern, self.out)
                if m:
                    return m
                left = deadline - time.monotonic()
                if self.ended or left <= 0:
                    return None
                self.cond.wait(left)

    def finish(self, seconds):
        try:
            status = self.proc.wait(seconds)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
            return None
        self.thread.join(10)
        return status


def fail(msg, child=None, driver=None, out_dir=None):
    if driver is not None and out_dir is not None:
        try:
            driver.save_screenshot(os.path.join(out_dir, "live_view_failure.png"))
        except Exception:  # noqa: BLE001 - best effort on the way out
            pass
    if child is not None:
        print("---- output of msmcal (last 6000 chars) ----")
        print(child.out[-6000:])
    print("FAIL: " + msg, flush=True)
    sys.exit(1)


def start_browser(profile):
    o = webdriver.ChromeOptions()
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
              "--window-size=1500,1100", "--force-prefers-reduced-motion",
              "--user-data-dir=" + profile):
        o.add_argument(a)
    o.binary_location = "/usr/lib/chromium/chromium"
    return webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=o)


def text(driver, element_id):
    try:
        return driver.find_element(By.ID, element_id).text
    except StaleElementReferenceException:
        return ""


def enabled(driver, element_id):
    return driver.find_element(By.ID, element_id).is_enabled()


def wait(driver, what, seconds, cond, child, out_dir):
    try:
        return WebDriverWait(driver, seconds, poll_frequency=0.25).until(lambda d: cond(d))
    except Exception:  # noqa: BLE001 - TimeoutException, or the page went away
        fail("page: %s not within %d s (state %r, block %r)" %
             (what, seconds, text(driver, "state"), text(driver, "block")), child, driver, out_dir)


def wait_instruction(driver, previous_block, child, out_dir):
    """Waits for an instruction other than `previous_block` (or the end); returns the block."""
    def cond(d):
        st = text(d, "state")
        if st in ("done", "aborted"):
            return st
        if st == "waiting" and text(d, "block") not in ("", previous_block) and enabled(d, "ready"):
            return text(d, "block")
        return False
    return wait(driver, "the next instruction after %r" % previous_block, PROMPT_DEADLINE_S,
                cond, child, out_dir)


def check_outputs_off_in_transcript(path):
    """True when, on both units, the last output query after the last `ON` was answered 0;0."""
    lines = open(path).read().splitlines()
    for unit in ("unit1", "unit2"):
        last_on = max((i for i, l in enumerate(lines)
                       if l.startswith(unit + " > ") and re.search(r"OUTP\d ON", l)), default=-1)
        answers = [lines[i + 1] for i in range(last_on + 1, len(lines) - 1)
                   if lines[i] == unit + " > OUTP1?;:OUTP2?"]
        if not answers or answers[-1] != unit + " < 0;0":
            return False, unit, answers
    return True, None, None


def run(msmcal, out_dir, mode):
    os.makedirs(out_dir, exist_ok=True)
    for old in ("live_view_step1.png", "live_view_failure.png"):  # from an earlier run
        if os.path.exists(os.path.join(out_dir, old)):
            os.remove(os.path.join(out_dir, old))
    work = tempfile.mkdtemp(prefix="live_view_browser_")
    driver = None
    child = None
    try:
        cfg = os.path.join(work, "tiny.yaml")
        with open(cfg, "w") as f:
            f.write(TINY)
        session = os.path.join(work, "session")
        child = Msmcal([msmcal, "demo", "--guided", "--ui", "web:0", "--config", cfg, "--out",
                        session])
        m = child.wait_for(r"live view: open (http://127\.0\.0\.1:\d+/) ", 120)
        if not m:
            fail("no live view URL printed", child)
        url = m.group(1)
        driver = start_browser(os.path.join(work, "profile"))
        driver.get(url)

        # Step 1, frame 1: nothing taken yet; the image is the preview pump's.
        block = wait_instruction(driver, "", child, out_dir)
        if block in ("done", "aborted"):
            fail("the session ended before the first instruction", child, driver, out_dir)
        if "Step 1, frame 1 of" not in text(driver, "instruction"):
            fail("first instruction is not step 1, frame 1: %r" % text(driver, "instruction"),
                 child, driver, out_dir)
        if "Mount the sliding plate at pose 1 of 4" not in text(driver, "instruction"):
            fail("first instruction does not say to mount the sliding plate at pose 1", child,
                 driver, out_dir)
        if not text(driver, "counters").startswith("Step 1, frame 1 of"):
            fail("counters: %r" % text(driver, "counters"), child, driver, out_dir)
        wait(driver, "a live camera image", PROMPT_DEADLINE_S,
             lambda d: d.execute_script(
                 "const i = document.getElementById('live-image');"
                 "return i.complete && i.naturalWidth > 0 && i.src.indexOf('/api/image.jpg') >= 0;"),
             child, out_dir)
        wait(driver, "the live caption", 30,
             lambda d: text(d, "caption").startswith("LIVE step1/0000.png"), child, out_dir)
        if "GENERATOR OUTPUTS ON" not in text(driver, "outputs"):
            fail("outputs indicator at step 1: %r" % text(driver, "outputs"), child, driver,
                 out_dir)
        if "this page controls" not in text(driver, "control"):
            fail("the first page is not the controller: %r" % text(driver, "control"), child,
                 driver, out_dir)
        shot = os.path.join(out_dir, "live_view_step1.png")
        driver.save_screenshot(shot)
        with open(shot, "rb") as f:
            if f.read(8) != b"\x89PNG\r\n\x1a\n":
                fail("the screenshot is not a PNG", child, driver, out_dir)
        print("screenshot: " + shot)

        prompts = 1
        if mode == "complete":
            # A second tab is another page: it watches.
            first = driver.current_window_handle
            driver.switch_to.new_window("tab")
            driver.get(url)
            wait(driver, "the second tab watching", 30,
                 lambda d: "watching" in text(d, "control") and text(d, "state") == "waiting",
                 child, out_dir)
            if enabled(driver, "ready") or enabled(driver, "abort"):
                fail("the watching tab's buttons are enabled", child, driver, out_dir)
            driver.close()
            driver.switch_to.window(first)

        repeated = reloaded = False
        step2_seen = False
        while True:
            instruction = text(driver, "instruction")
            if mode == "abort" and text(driver, "counters").startswith("Step 2, frame"):
                step2_seen = True
                driver.find_element(By.ID, "abort").click()
                # The page shows `aborted` while msmcal still serves it; msmcal may also end
                # first (the abort's outcome is then checked from its files below).
                wait(driver, "state aborted", END_DEADLINE_S,
                     lambda d: text(d, "state") == "aborted" or child.proc.poll() is not None,
                     child, out_dir)
                break
            if mode == "complete" and prompts == 2 and not repeated:
                driver.find_element(By.ID, "repeat").click()
                # The same block again, still waiting (the page flashes it).
                wait(driver, "repeat answered", 30,
                     lambda d: d.execute_script(
                         "return document.getElementById('instruction')"
                         ".classList.contains('flash')"), child, out_dir)
                if text(driver, "state") != "waiting" or text(driver, "instruction") != instruction:
                    fail("Repeat changed the instruction or the state", child, driver, out_dir)
                repeated = True
            if mode == "complete" and prompts == 3 and not reloaded:
                driver.refresh()
                wait(driver, "the reloaded page in control", 30,
                     lambda d: text(d, "state") == "waiting" and text(d, "block") == block and
                     "this page controls" in text(d, "control") and enabled(d, "ready"),
                     child, out_dir)
                reloaded = True
            driver.find_element(By.ID, "ready").click()
            nxt = wait_instruction(driver, block, child, out_dir)
            if nxt in ("done", "aborted"):
                break
            block = nxt
            prompts += 1

        final_state = text(driver, "state")
        if mode == "complete":
            if final_state != "done":
                fail("final state %r" % final_state, child, driver, out_dir)
            totals = text(driver, "totals")
            if not re.match(r"\d+ accepted, 0 rejected", totals):
                fail("totals on the page: %r" % totals, child, driver, out_dir)
            wait(driver, "outputs off", 60,
                 lambda d: text(d, "outputs") == "generator outputs off", child, out_dir)
            status = child.finish(END_DEADLINE_S)
            if status != 0:
                fail("exit status %r" % status, child)
            total = int(re.search(r"/(\d+)\]", block).group(1))
            if prompts != total:
                fail("%d instructions answered, %d announced" % (prompts, total), child)
            if not repeated or not reloaded:
                fail("repeat=%s reload=%s" % (repeated, reloaded), child)
            if not os.path.exists(os.path.join(session, "session.yaml")):
                fail("no session.yaml", child)
            if "ok (web page)." not in child.out or "[waiting for the web page" not in child.out:
                fail("the terminal does not echo the instructions and answers", child)
            print("ok: %d instructions answered from the browser (one Repeat, one reload), "
                  "state done, exit 0" % prompts)
        else:
            if not step2_seen:
                fail("no step-2 instruction reached", child, driver, out_dir)
            if child.proc.poll() is None:
                wait(driver, "outputs off after the abort", 60,
                     lambda d: text(d, "outputs") == "generator outputs off" or
                     child.proc.poll() is not None, child, out_dir)
            status = child.finish(END_DEADLINE_S)
            if status is None or status == 0:
                fail("aborted session: exit status %r" % status, child)
            ok, unit, answers = check_outputs_off_in_transcript(
                os.path.join(session, "generators_transcript.txt"))
            if not ok:
                fail("the mock generators did not report every output off on %s: %r" %
                     (unit, answers), child)
            with open(os.path.join(session, "session_log.txt")) as f:
                log = f.read()
            if "safe state: generator outputs off (confirmed)" not in log:
                fail("session_log.txt: no confirmed safe state", child)
            if "operator aborted the session from the web page" not in log:
                fail("session_log.txt does not record the abort", child)
            db = sqlite3.connect(os.path.join(session, "session.db"))
            rows = db.execute("SELECT kind, message FROM events "
                              "WHERE message LIKE '%operator aborted%'").fetchall()
            db.close()
            if not rows:
                fail("the journal's events do not record the abort", child)
            if os.path.exists(os.path.join(session, "session.yaml")):
                fail("an aborted session wrote session.yaml", child)
            print("ok: aborted from the browser at a step-2 instruction after %d instructions: "
                  "exit %d, mock generators report outputs off, journal event %r" %
                  (prompts, status, rows[0]))
    finally:
        if driver is not None:
            driver.quit()
        if child is not None and child.proc.poll() is None:
            child.proc.kill()
            child.proc.wait()
        shutil.rmtree(work, ignore_errors=True)


def main():
    if len(sys.argv) != 4 or sys.argv[3] not in ("complete", "abort"):
        print(__doc__)
        sys.exit(2)
    run(os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2]), sys.argv[3])


if __name__ == "__main__":
    main()
