#!/usr/bin/python3
"""The live view of a lab session on the twin, over HTTP without a browser (issue 19).

`msmcal plan --rig RIG` designs a small plan; `msmcal mock rig --rig RIG --hands SOCK` serves the
twin; `msmcal session run --rig RIG --plan P --out OUT --ui web:0` runs the session with the live
view's page as its operator. This test is the page and the person at the rig: it claims control
(`POST /api/claim`), follows the server-sent events (`GET /api/events`), and at every instruction
(state `waiting`) performs the set-up on the twin (`msmcal mock hands` with the state's
`prompt.setup`, the set-up as a hook program gets it), then answers Ready (`POST /api/ready`
with the prompt's id), until the state says `done`. Checked:

- the first step-1 instruction comes with a camera image (`GET /api/image.jpg`: a JPEG, the
  preview pump's, before any frame was taken) and the generator outputs indicator on;
- during the Hall background recording the page keeps a live camera image: the state's `live`
  caption says the recording runs and the image sequence advances while `rig.hall_recording` is
  `background` (it stood still before: the preview pump ran only while an instruction waited);
- `session run` exits 0 (acquisition, solve, Hall calibration), session.yaml is written, every
  instruction was answered once, and the twin's generators answer `OUTP1?;:OUTP2?` with `0;0`.

No sleeps: msmcal's output and the event stream are read by threads and waited on with
conditions. Runs in its own network namespace (ports 15025/15026, GigE Vision 3956).

usage: live_view_twin_http_test.py MSMCAL SOURCE_DIR
"""
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import urllib.error
import urllib.request

# The whole run, solve included: 114 s here with the load average at 18 on 2 cores (8
# instructions, 3 + 9 frames, 2 s and ~20 s of Hall recording; the acquisition ~85 s of it).
DEADLINE_S = 240


from cli_testlib import Lines, fail, scpi  # tests/app/cli_testlib.py

class Page:
    """The page's side: the claim, the event stream (a thread), the requests."""

    def __init__(self, url):
        self.url = url.rstrip("/")
        self.controller = self.post("/api/claim")["controller"]
        self.states, self.ended = [], False
        self.cv = threading.Condition()
        self.stream = urllib.request.urlopen(
            self.url + "/api/events?controller=" + self.controller, timeout=30)
        threading.Thread(target=self._read, daemon=True).start()

    def post(self, path):
        req = urllib.request.Request(self.url + path, data=b"", method="POST",
                                     headers={"X-Msmcal-Request": "1"})
        with urllib.request.urlopen(req, timeout=10) as r:
            return json.loads(r.read())

    def image(self):
        try:
            with urllib.request.urlopen(self.url + "/api/image.jpg", timeout=10) as r:
                return int(r.headers["X-Image-Sequence"]), r.read()
        except urllib.error.HTTPError as e:
            if e.code == 404:
                return None, b""
            raise

    def _read(self):
        try:
            for raw in self.stream:
                line = raw.decode().rstrip("\r\n")
                if line.startswith("data: "):
                    with self.cv:
                        self.states.append(json.loads(line[6:]))
                        self.cv.notify_all()
        except OSError:
            pass  # msmcal ended: the connection goes
        with self.cv:
            self.ended = True
            self.cv.notify_all()

    def next_state(self, seen, deadline_s):
        """The first state after the `seen` first ones (None at the end of the stream)."""
        end = time.monotonic() + deadline_s
        with self.cv:
            while len(self.states) <= seen:
                left = end - time.monotonic()
                if self.ended or left <= 0:
                    return None
                self.cv.wait(left)
            return self.states[seen]


def main():
    msmcal, source = sys.argv[1], sys.argv[2]
    t0 = time.monotonic()
    tmp = tempfile.mkdtemp(prefix="live_view_twin_")
    sock = os.path.join(tmp, "hands.sock")
    rig = os.path.join(tmp, "rig.yaml")
    text = open(os.path.join(source, "config", "rig.yaml")).read()
    # Smaller than tests/app/twin_session_hook_test.py's (the page's loop costs a process per
    # set-up): short Hall recordings (the background one 2 s, to see its live images), 4 sliding
    # plate poses without background or identification frames (it still solves), one exposure
    # per step-1 frame, fewer triggers and step-2 frames.
    for a, b in [("device: /dev/ttyACM0", "device: " + os.path.join(tmp, "tty")),
                 # the camera at half resolution, same field of view: a quarter of the pixels
                 ("width: 2448", "width: 1224"), ("height: 2048", "height: 1024"),
                 ("fx: 2000", "fx: 1000"), ("fy: 2000", "fy: 1000"),
                 ("cx: 1223.5", "cx: 611.5"), ("cy: 1023.5", "cy: 511.5"),
                 ("hall_background_s: 12", "hall_background_s: 2"),
                 ("hall_actual_min_s: 15", "hall_actual_min_s: 1"),
                 ("  exposures: 3 ", "  exposures: 1 "),
                 ("spacing: 0.25", "spacing: 0.9"),
                 ("  poses: 7\n", "  poses: 4\n"),
                 ("background_frames: true", "background_frames: false"),
                 ("identification_frames: true", "identification_frames: false"),
                 ("neutral_frames: 2", "neutral_frames: 1"),
                 ("fast_only_frames: 3", "fast_only_frames: 1")]:
        if a not in text:
            fail("config/rig.yaml has no '%s'" % a)
        text = text.replace(a, b, 1)
    open(rig, "w").write(text)
    plan = os.path.join(tmp, "plan")
    p = subprocess.run([msmcal, "plan", "--rig", rig, "--out", plan], capture_output=True,
                       text=True, timeout=120)
    if p.returncode != 0:
        fail("plan: %s %s" % (p.stdout, p.stderr))

    twin = subprocess.Popen([msmcal, "mock", "rig", "--rig", rig, "--hands", sock],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    session = None
    try:
        if not Lines(twin, "twin").wait_for(r"^twin: ready", 60):
            fail("the twin did not get ready")
        out = os.path.join(tmp, "session")
        session = subprocess.Popen(
            [msmcal, "session", "run", "--rig", rig, "--plan", plan, "--out", out, "--ui",
             "web:0"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
            text=True, errors="replace")
        lines = Lines(session, "session")
        m = lines.wait_for(r"live view: open (http://\S+) in a browser", 60)
        if not m:
            fail("no live view URL printed")
        page = Page(m.group(1))

        answered, seen, first_step1 = set(), 0, True
        recording_images = set()  # image sequences shown while the background recording ran
        recording_captions = set()
        final = None
        while True:
            left = DEADLINE_S - (time.monotonic() - t0)
            st = page.next_state(seen, max(1.0, left))
            if st is None:
                break
            seen += 1
            if st["rig"]["hall_recording"] == "background":
                live = st.get("live") or {}
                if live.get("source") == "live":
                    recording_captions.add(live.get("caption", ""))
                    recording_images.add(st["image"]["sequence"])
            if st["state"] in ("done", "aborted"):
                final = st
                break
            prompt = st["prompt"]
            if st["state"] != "waiting" or not prompt["waiting"] or prompt["id"] in answered:
                continue
            if first_step1 and prompt["step"] == 1:
                first_step1 = False
                # The preview pump's first image (the camera streams while the prompt waits).
                shown = st
                while shown is not None and shown["image"]["sequence"] == 0:
                    shown = page.next_state(seen, 30)
                    seen += shown is not None
                if shown is None:
                    fail("no camera image while the first step-1 instruction waits")
                seq, jpeg = page.image()
                if not jpeg.startswith(b"\xff\xd8"):
                    fail("no camera image at the first step-1 instruction")
                if not st["rig"]["outputs_on"]:
                    fail("the generator outputs indicator is off at step 1")
            setup = prompt["setup"]
            if not isinstance(setup, dict) or setup.get("kind") != "setup":
                fail("instruction %s without its set-up: %r" % (prompt["id"], setup))
            h = subprocess.run([msmcal, "mock", "hands", "--socket", sock],
                               input=json.dumps(setup) + "\n", capture_output=True, text=True,
                               timeout=60)
            if h.returncode != 0:
                fail("mock hands: exit %d: %s %s" % (h.returncode, h.stdout, h.stderr))
            answered.add(prompt["id"])
            print("[%6.1f s] instruction %d (%s) set up on the twin: Ready" %
                  (time.monotonic() - t0, prompt["id"], prompt["title"]), flush=True)
            page.post("/api/ready?controller=%s&prompt=%d" % (page.controller, prompt["id"]))
        if final is None or final["state"] != "done":
            fail("the page did not say done: %s" % (final and final["state"]))
        try:
            rc = session.wait(timeout=max(1.0, DEADLINE_S - (time.monotonic() - t0)))
        except subprocess.TimeoutExpired:
            fail("session run did not end (solve, Hall calibration) in time")
        if rc != 0:
            fail("session run: exit status %d" % rc)
        if not os.path.exists(os.path.join(out, "session.yaml")):
            fail("no session.yaml")
        if not any("background recording running" in c for c in recording_captions):
            fail("no live camera image during the Hall background recording (captions %r)" %
                 sorted(recording_captions))
        if len(recording_images) < 2:
            fail("the live image did not advance during the background recording (%r)" %
                 sorted(recording_images))
        for port in (15025, 15026):
            reply = scpi(port, "OUTP1?;:OUTP2?")
            if reply != "0;0":
                fail("twin generator on port %d: OUTP1?;:OUTP2? = %s" % (port, reply))
        print("%d instructions answered over HTTP; %d live images during the background "
              "recording; session done, exit 0, outputs off (%.1f s)" %
              (len(answered), len(recording_images), time.monotonic() - t0), flush=True)
    finally:
        if session and session.poll() is None:
            session.kill()
            session.wait()
        twin.send_signal(signal.SIGTERM)
        try:
            twin.wait(timeout=20)
        except subprocess.TimeoutExpired:
            twin.kill()
        shutil.rmtree(tmp, ignore_errors=True)
    print("PASS")


if __name__ == "__main__":
    main()
